//! Grid storage for contact between bodies: one dense grid velocity field per contact
//! field (field 0 holds the bodies no contact pair names, when there are any), with the
//! field's mass gradient (for the contact normal) and the particle volume it maps to each
//! node (for the gap test). Allocated once, only for scenes with a `contact` section; every
//! buffer is reused from step to step.

use super::binning::SlabBins;
use super::cohesive::{Cohesive, Precrack};
use super::contact::FieldLaws;
use super::parallel::SharedSlice;
use super::particle_to_grid::{P2gParams, particle_to_grid};
use super::stencil::Stencil;
use crate::grid::Grid;
use crate::kernels::Kernel;
use crate::math::{Vector, determinant};
use crate::particles::Particles;
use crate::scene::{MAX_CONTACT_FIELDS, Scene};
use rayon::prelude::*;

/// The grid velocity fields of a contact scene.
pub(crate) struct MultiField<const D: usize> {
    /// One grid per field: mass, momentum → velocity, and FLIP's force and old velocity.
    pub(crate) grids: Vec<Grid<D>>,
    /// Each field's particles, binned into the slabs of the coloured P2G.
    bins: Vec<SlabBins>,
    /// Σ_p m_p ∇w_ip of each field (grid units, ∇ with respect to the particle position): it
    /// points out of the field's body.
    pub(crate) gradient: Vec<Vec<Vector<D>>>,
    /// Σ_p V_p w_ip of each field: the particle volume it maps to each node.
    pub(crate) volume: Vec<Vec<f64>>,
    /// The law between every two fields.
    pub(crate) laws: FieldLaws,
    /// Energy friction dissipated so far (≥ 0; `ContactStats::friction_work`).
    pub(crate) dissipated: f64,
    /// Whether a contact law acted in the last step.
    pub(crate) touching: bool,
    /// The bonded interfaces' node states (only with a cohesive pair).
    pub(crate) cohesive: Option<Cohesive<D>>,
}

/// The contact field of every body of `scene` (by body index), the number of fields and the
/// law between every two; `None` without a `contact` section. Bodies no pair names share
/// one field; bodies named in pairs get one field per distinct name.
pub(crate) fn body_fields(scene: &Scene) -> Option<(Vec<u8>, usize, FieldLaws)> {
    let contact = scene.contact.as_ref()?;
    let (keys, fields) = contact.fields(scene);
    let count = keys.len();
    let mut laws = FieldLaws::bonded(count);
    let field_of = |name: &str| keys.iter().position(|k| *k == Some(name));
    for pair in &contact.pairs {
        for (j, a) in pair.bodies.iter().enumerate() {
            for b in &pair.bodies[..j] {
                if let (Some(f), Some(g)) = (field_of(a), field_of(b))
                    && f < count
                    && g < count
                    && f != g
                {
                    laws.set(f, g, pair.law);
                    if let Some(shape) = &pair.precrack {
                        laws.precracks.push(Precrack {
                            pair: [f.min(g) as u8, f.max(g) as u8],
                            shape: shape.clone(),
                        });
                    }
                }
            }
        }
    }
    Some((fields, count, laws))
}

impl<const D: usize> MultiField<D> {
    /// Fields shaped like `grid` for `counts[f]` particles each.
    pub(crate) fn new(
        grid: &Grid<D>,
        flip: bool,
        span: usize,
        counts: &[usize],
        mut laws: FieldLaws,
    ) -> Self {
        let cells = grid.cells;
        let cohesive = laws
            .has_cohesive()
            .then(|| Cohesive::new(grid.len(), std::mem::take(&mut laws.precracks)));
        Self {
            grids: counts
                .iter()
                .map(|_| Grid::new(grid.origin, cells, grid.dx, flip))
                .collect(),
            bins: counts
                .iter()
                .map(|&n| SlabBins::new(grid.nodes[0], span, n))
                .collect(),
            gradient: counts
                .iter()
                .map(|_| vec![Vector::<D>::zeros(); grid.len()])
                .collect(),
            volume: counts.iter().map(|_| vec![0.0; grid.len()]).collect(),
            laws,
            dissipated: 0.0,
            touching: false,
            cohesive,
        }
    }

    /// Bytes held by the field arrays.
    pub(crate) fn bytes(&self) -> usize {
        self.grids.iter().map(Grid::bytes).sum::<usize>()
            + self
                .gradient
                .iter()
                .map(|g| g.capacity() * std::mem::size_of::<Vector<D>>())
                .sum::<usize>()
            + self.volume.iter().map(|v| v.capacity() * 8).sum::<usize>()
            + self.cohesive.as_ref().map_or(0, Cohesive::bytes)
    }

    /// P2G into every field (each field's particles only, with `params`), the fields' mass
    /// gradients and volumes, and the total mass into `grid` (physics operators read it).
    pub(crate) fn scatter<K: Kernel>(
        &mut self,
        grid: &mut Grid<D>,
        particles: &Particles<D>,
        bins: &SlabBins,
        params: P2gParams<D>,
    ) {
        bins.split_by_field(&particles.contact_field, &mut self.bins);
        for (field, field_bins) in self.grids.iter_mut().zip(&self.bins) {
            field.clear();
            particle_to_grid::<D, K>(field, particles, field_bins, params);
        }
        self.scatter_geometry::<K>(grid, particles, bins);
        let grids = &self.grids;
        grid.mass
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, m)| *m = grids.iter().map(|g| g.mass[i]).sum());
    }

    /// Mass gradients and nodal volumes of every field, with the coloured slabs of P2G.
    fn scatter_geometry<K: Kernel>(
        &mut self,
        grid: &Grid<D>,
        particles: &Particles<D>,
        bins: &SlabBins,
    ) {
        let mut gradient_out: [Option<SharedSlice<Vector<D>>>; MAX_CONTACT_FIELDS] =
            [None; MAX_CONTACT_FIELDS];
        let mut volume_out: [Option<SharedSlice<f64>>; MAX_CONTACT_FIELDS] =
            [None; MAX_CONTACT_FIELDS];
        for (f, (g, v)) in self.gradient.iter_mut().zip(&mut self.volume).enumerate() {
            g.par_iter_mut().for_each(|x| *x = Vector::<D>::zeros());
            v.par_iter_mut().for_each(|x| *x = 0.0);
            gradient_out[f] = Some(SharedSlice::new(g));
            volume_out[f] = Some(SharedSlice::new(v));
        }
        let stride = grid.stride;
        for colour in 0..2 {
            (0..bins.slab_count())
                .into_par_iter()
                .filter(|s| s % 2 == colour)
                .for_each(|slab| {
                    for &p in bins.slab(slab) {
                        let p = p as usize;
                        let f = particles.contact_field[p] as usize;
                        let (Some(gradient), Some(volume)) = (gradient_out[f], volume_out[f])
                        else {
                            continue;
                        };
                        let half = if K::USES_PARTICLE_SIZE {
                            particles.half_size[p]
                        } else {
                            0.0
                        };
                        let stencil = Stencil::<D>::new::<K>(grid, &particles.position[p], half);
                        let m = particles.mass[p];
                        let v =
                            particles.volume0[p] * determinant(&particles.deformation_gradient[p]);
                        stencil.for_each::<K>(&stride, |i, w, grad, _| {
                            // SAFETY: the slab colouring gives this task exclusive access to
                            // every node its particles touch (as in P2G).
                            unsafe {
                                *gradient.get(i) += grad * m;
                                *volume.get(i) += w * v;
                            }
                        });
                    }
                });
        }
    }
}

impl<const D: usize> MultiField<D> {
    /// Writes what contact keeps from step to step (friction work, whether bodies touched,
    /// the bonded interfaces) into a checkpoint.
    pub(crate) fn save(&self, c: &mut crate::checkpoint::Checkpoint) {
        let touching = if self.touching { 1.0 } else { 0.0 };
        c.put("contact.totals", vec![self.dissipated, touching]);
        if let Some(cohesive) = &self.cohesive {
            cohesive.save(c);
        }
    }

    /// Takes back what [`MultiField::save`] wrote.
    pub(crate) fn restore(
        &mut self,
        c: &crate::checkpoint::Checkpoint,
    ) -> Result<(), crate::checkpoint::CheckpointError> {
        let t = c.get("contact.totals", 2)?;
        self.dissipated = t[0];
        self.touching = t[1] != 0.0;
        if let Some(cohesive) = &mut self.cohesive {
            cohesive.restore(c)?;
        }
        Ok(())
    }
}
