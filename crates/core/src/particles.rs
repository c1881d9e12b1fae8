//! Particle storage: structure of arrays, one `Vec` per field, allocated only when the scene
//! needs the field (no affine matrices without APIC, no velocity gradient unless a material
//! asks, no initial positions unless a reference needs them).

use crate::material::Material;
use crate::math::{Matrix, Vector};
use crate::physics::ParticleFields;
use std::ops::Range;
use std::sync::Arc;

/// The particles of one material, stored contiguously so a material updates them as a batch.
pub struct MaterialGroup {
    /// The material's name in the scene.
    pub name: String,
    /// The constitutive law.
    pub material: Arc<dyn Material>,
    /// Particle indices of this group.
    pub range: Range<usize>,
    /// The factor the stress update applies to the free strain in the plane (1, or the
    /// law's plane-strain expansion with `solver.free_strain_2d: "plane_strain"`).
    pub free_strain_factor: f64,
    /// Whether this group's law takes a stretch across the plane (2D with
    /// `solver.free_strain_2d` `plane_strain` or `generalized_plane_strain`, and a law that
    /// says `plane_strain_stress`): its free strain's, and generalized plane strain's ε₀.
    /// Then `free_strain_factor` is 1.
    pub free_strain_across_plane: bool,
    /// The law's declared state fields for this group's particles, one `Vec` per field
    /// (`components` numbers per particle).
    pub state: Vec<Vec<f64>>,
    /// A solid held in place by incompressible mechanics (`scene::held_bodies`): its
    /// particles take no part in the transfers or the stress update; physics still acts.
    pub held: bool,
}

/// Whether particle `p` belongs to a held group of `groups` (for passes that hold the
/// particle arrays apart from the groups).
#[inline]
pub fn held_in(groups: &[MaterialGroup], p: usize) -> bool {
    groups.iter().any(|g| g.held && g.range.contains(&p))
}

/// All particles, as parallel arrays indexed by particle.
pub struct Particles<const D: usize> {
    /// Current position.
    pub position: Vec<Vector<D>>,
    /// Velocity.
    pub velocity: Vec<Vector<D>>,
    /// Mass (constant).
    pub mass: Vec<f64>,
    /// Reference volume.
    pub volume0: Vec<f64>,
    /// Deformation gradient F.
    pub deformation_gradient: Vec<Matrix<D>>,
    /// Cauchy stress.
    pub stress: Vec<Matrix<D>>,
    /// σzz in 2D (plane strain): the stress across the plane the held third direction
    /// carries, from laws that say `plane_strain_stress` (0 for others); empty in 3D.
    pub stress_zz: Vec<f64>,
    /// APIC affine velocity matrix C (empty unless APIC).
    pub affine: Vec<Matrix<D>>,
    /// Velocity gradient of the last step (empty unless a material needs it).
    pub velocity_gradient: Vec<Matrix<D>>,
    /// Half width of the undeformed particle in cells (empty unless GIMP).
    pub half_size: Vec<f64>,
    /// Position at time 0 (empty unless a reference needs it).
    pub initial_position: Vec<Vector<D>>,
    /// Each particle's share of the scene's dead loads, N (empty without `loads`).
    pub external_force: Vec<Vector<D>>,
    /// Index of the particle in the output order (particles are reordered for locality;
    /// output is always written in the original order).
    pub id: Vec<u32>,
    /// Grid velocity field of each particle for contact between bodies (0: the shared
    /// field); empty unless the scene has a `contact` section.
    pub contact_field: Vec<u8>,
    /// Contiguous ranges of particles sharing a material.
    pub groups: Vec<MaterialGroup>,
    /// Scalar fields the scene's physics operators created (empty without physics).
    pub shared: ParticleFields,
}

impl<const D: usize> Particles<D> {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Whether some group is held in place (a solid in incompressible mechanics).
    #[inline]
    pub fn any_held(&self) -> bool {
        self.groups.iter().any(|g| g.held)
    }

    /// Whether particle `p` belongs to a held group; ask only when [`Self::any_held`].
    #[inline]
    pub fn is_held(&self, p: usize) -> bool {
        held_in(&self.groups, p)
    }

    /// Bytes of particle storage actually allocated, material state included.
    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        let v = size_of::<Vector<D>>();
        let m = size_of::<Matrix<D>>();
        let state: usize = self
            .groups
            .iter()
            .flat_map(|g| g.state.iter())
            .map(|s| s.capacity() * 8)
            .sum();
        (self.position.capacity()
            + self.velocity.capacity()
            + self.initial_position.capacity()
            + self.external_force.capacity())
            * v
            + (self.mass.capacity()
                + self.volume0.capacity()
                + self.half_size.capacity()
                + self.stress_zz.capacity())
                * 8
            + (self.deformation_gradient.capacity()
                + self.stress.capacity()
                + self.affine.capacity()
                + self.velocity_gradient.capacity())
                * m
            + self.id.capacity() * 4
            + self.contact_field.capacity()
            + state
            + self.shared.bytes()
    }

    /// Bytes per particle (see [`Particles::bytes`]).
    pub fn bytes_per_particle(&self) -> f64 {
        if self.is_empty() {
            0.0
        } else {
            self.bytes() as f64 / self.len() as f64
        }
    }
}
