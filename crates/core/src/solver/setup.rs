//! Building a [`Simulation`] from a validated scene: the grid, the particles of every body
//! grouped by material, material state, output buffers, physics slots and the mode.

use super::DimensionDispatch;
use super::binning::{Reorder, SlabBins};
use super::multi_field::{MultiField, body_fields};
use super::output_staging::output_fields;
use super::simulation::{PhysicsSlot, Settings, Simulation};
use super::stats::KinematicStats;
use super::stress_update::{StressScratch, StressStats};
use super::volume_averaging::VolumeAverage;
use crate::boundary::Boundaries;
use crate::grid::Grid;
use crate::kernels::Kernel;
use crate::material::Material;
use crate::math::{Matrix, Vector, vector_from_slice};
use crate::particles::{MaterialGroup, Particles};
use crate::physics::{GroupView, Interpolation, ParticleFields, PhysicsReport};
use crate::scene::{INTERFACE_DAMAGE, Transfer, ValidatedScene};

impl<const D: usize, K: Kernel> Simulation<D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Builds grid and particles for a validated scene; allocates only what it needs.
    pub fn new(v: &ValidatedScene) -> Self {
        let s = &v.scene;
        let dx = s.domain.cell_size;
        let pad = crate::boundary::GRID_PADDING;
        let mut min: Vector<D> = vector_from_slice(&s.domain.min);
        let mut domain_cells = [1usize; 3];
        let mut cells = [1usize; 3];
        for d in 0..D {
            domain_cells[d] = ((s.domain.max[d] - s.domain.min[d]) / dx - 1e-9).ceil() as usize;
            cells[d] = domain_cells[d] + 2 * pad;
            min[d] -= pad as f64 * dx;
        }
        // FLIP and XPIC keep the forces apart from the momentum and the velocity before them.
        let flip = matches!(s.solver.transfer, Transfer::Flip | Transfer::Xpic);
        let mut grid = Grid::new(min, cells, dx, flip);
        if s.solver.transfer == Transfer::Xpic {
            grid.enable_xpic();
        }

        let reference = v.reference.as_ref().map(|r| r.start());
        let fbar = s.solver.anti_locking == crate::scene::AntiLocking::Fbar;
        let implicit = matches!(s.solver.mechanics, crate::scene::Mechanics::Implicit(_));
        // Explicit F-bar averages this step's volume change, which it reads from the
        // gradient.
        let needs_gradient =
            v.materials.values().any(|m| m.needs_velocity_gradient()) || (fbar && !implicit);
        let n = v.particle_count();
        let alloc_if = |yes: bool| if yes { n } else { 0 };
        let mut particles = Particles::<D> {
            position: Vec::with_capacity(n),
            velocity: Vec::with_capacity(n),
            mass: Vec::with_capacity(n),
            volume0: Vec::with_capacity(n),
            deformation_gradient: vec![Matrix::<D>::identity(); n],
            stress: vec![Matrix::<D>::zeros(); n],
            stress_zz: vec![0.0; alloc_if(D == 2)],
            affine: vec![Matrix::<D>::zeros(); alloc_if(s.solver.transfer == Transfer::Apic)],
            velocity_gradient: vec![Matrix::<D>::zeros(); alloc_if(needs_gradient)],
            half_size: Vec::with_capacity(alloc_if(K::USES_PARTICLE_SIZE)),
            initial_position: Vec::with_capacity(alloc_if(
                reference
                    .as_ref()
                    .is_some_and(|r| r.needs_initial_positions()),
            )),
            external_force: Vec::with_capacity(alloc_if(!s.loads.is_empty())),
            id: Vec::with_capacity(n),
            contact_field: Vec::with_capacity(alloc_if(s.contact.is_some())),
            groups: Vec::new(),
            shared: ParticleFields::default(),
        };
        for (_, physics) in &v.physics {
            for spec in physics.fields() {
                particles.shared.add(spec, n);
            }
        }
        if !particles.shared.contains(crate::physics::PLASTIC_WORK)
            && v.materials.values().any(|m| m.reports_plastic_work())
        {
            // The energy ledger counts plastic work also without a physics that heats with it.
            let spec = crate::physics::SharedFieldSpec {
                name: crate::physics::PLASTIC_WORK,
                initial: 0.0,
            };
            particles.shared.add(spec, n);
        }
        if s.contact.as_ref().is_some_and(|c| c.has_cohesive())
            && s.output.fields.iter().any(|f| f == INTERFACE_DAMAGE)
        {
            let spec = crate::physics::SharedFieldSpec {
                name: INTERFACE_DAMAGE,
                initial: 0.0,
            };
            particles.shared.add(spec, n);
        }
        // Bodies of one material are stored together so each law sees contiguous batches.
        let mut order: Vec<&crate::scene::BodyParticles> = v.bodies.iter().collect();
        order.sort_by_key(|b| &s.bodies[b.body].material);
        let contact = body_fields(s);
        let mut field_counts = vec![0usize; contact.as_ref().map_or(0, |c| c.1)];
        let mut output_index = vec![0usize; v.bodies.len()];
        let mut next = 0;
        for b in &v.bodies {
            output_index[b.body] = next;
            next += b.volumes.len();
        }
        // Each load's picked volume, to split its force by volume.
        let load_volume: Vec<f64> = s
            .loads
            .iter()
            .map(|load| {
                v.bodies
                    .iter()
                    .flat_map(|b| b.positions.chunks_exact(D).zip(&b.volumes))
                    .filter(|(x, _)| crate::scene::in_box(load, x))
                    .map(|(_, volume)| volume)
                    .sum()
            })
            .collect();
        for body in order {
            let name = &s.bodies[body.body].material;
            let material = v.materials[name].clone();
            let start = particles.position.len();
            let count = body.volumes.len();
            if particles.groups.last().is_none_or(|g| &g.name != name) {
                let plane_strain = D == 2 && !s.solver.free_strain_2d.is_in_plane();
                // A law that works in 3D takes the free strain across the plane as its
                // stretch there; another stands in for it by expanding more in the plane.
                let free_strain_across_plane = plane_strain && material.plane_strain_stress();
                let free_strain_factor = if plane_strain && !free_strain_across_plane {
                    material.plane_strain_expansion()
                } else {
                    1.0
                };
                particles.groups.push(MaterialGroup {
                    name: name.clone(),
                    material: material.clone(),
                    range: start..start,
                    free_strain_factor,
                    free_strain_across_plane,
                    state: Vec::new(),
                    held: crate::scene::held_bodies::holds(&s.solver.mechanics, material.as_ref()),
                });
            }
            for p in 0..count {
                let x: Vector<D> = vector_from_slice(&body.positions[p * D..]);
                particles.position.push(x);
                particles
                    .velocity
                    .push(vector_from_slice(&body.velocities[p * D..]));
                particles.volume0.push(body.volumes[p]);
                particles.mass.push(body.volumes[p] * material.density());
                particles.id.push((output_index[body.body] + p) as u32);
                if K::USES_PARTICLE_SIZE {
                    particles.half_size.push(0.5 * body.spacing / dx);
                }
                if particles.initial_position.capacity() > 0 {
                    particles.initial_position.push(x);
                }
                if !s.loads.is_empty() {
                    let at = &body.positions[p * D..(p + 1) * D];
                    let mut force = Vector::<D>::zeros();
                    for (load, total) in s.loads.iter().zip(&load_volume) {
                        if crate::scene::in_box(load, at) {
                            force +=
                                vector_from_slice::<D>(&load.force) * (body.volumes[p] / total);
                        }
                    }
                    particles.external_force.push(force);
                }
            }
            if let Some((fields, _, _)) = &contact {
                let field = fields[body.body];
                particles
                    .contact_field
                    .extend(std::iter::repeat_n(field, count));
                field_counts[field as usize] += count;
            }
            particles.groups.last_mut().unwrap().range.end = start + count;
        }
        let inflow = super::incompressible::inflow::Inflows::<D>::new(v, &output_index);
        if let Some(inflow) = &inflow {
            let spec = crate::physics::SharedFieldSpec {
                name: crate::scene::INJECTED,
                initial: 1.0,
            };
            particles.shared.add(spec, n);
            inflow.mark_waiting(&mut particles);
        }
        for group in &mut particles.groups {
            let count = group.range.len();
            group.state = group
                .material
                .state_fields()
                .iter()
                .map(|spec| spec.initial_values(count, D))
                .collect();
        }

        let fields = output_fields::<D>(&s.output.fields, &particles);
        let staging = fields
            .iter()
            .map(|f| vec![0.0; f.components() * n])
            .collect();
        let settings = Settings {
            transfer: s.solver.transfer,
            flip_blend: s.solver.flip_blend,
            xpic_order: s.solver.xpic_order,
            mls: s.solver.mls,
            scheme: s.solver.scheme,
            cfl: s.solver.cfl,
            fixed_dt: s.solver.dt,
            max_cfl: s.solver.max_cfl,
            end_time: s.solver.end_time,
            end_when: s.solver.end_when.clone(),
            gravity: s
                .solver
                .gravity
                .as_deref()
                .map(vector_from_slice)
                .unwrap_or_else(Vector::<D>::zeros),
            damping: s.solver.damping,
            sort_interval: s.solver.sort_interval,
            frames: s.output.frames,
            checkpoint: s.output.checkpoint,
            max_speed: s.stop.max_speed,
            max_energy_growth: s.stop.max_energy_growth,
            min_dt: s.stop.min_dt,
            mechanics: s.solver.mechanics,
        };
        let group_views = particles
            .groups
            .iter()
            .map(|g| GroupView {
                name: g.name.clone(),
                range: g.range.clone(),
            })
            .collect();
        let physics: Vec<PhysicsSlot> = v
            .physics
            .iter()
            .map(|(_, p)| PhysicsSlot {
                physics: p.clone(),
                // Sized with the stencils (`Simulation::build_physics_stencils`); an
                // operator without stencils gets one row per grid node.
                scratch: vec![
                    if p.needs_interpolation() {
                        Vec::new()
                    } else {
                        vec![0.0; grid.len() * p.values_per_row()]
                    };
                    p.grid_arrays()
                ],
            })
            .collect();
        let needs_interpolation = physics.iter().any(|p| p.physics.needs_interpolation());
        let bins = SlabBins::new(grid.nodes[0], K::SPAN, n);
        let grid_nodes = grid.len();
        let contact =
            contact.map(|(_, _, laws)| MultiField::new(&grid, flip, K::SPAN, &field_counts, laws));
        grid.set_sparse(s.solver.sparse_grid(contact.is_some()));
        // Validation built the same levels from the same domain and refused the scene
        // where that failed.
        let refined = s.solver.refinement.as_ref().map(|r| {
            r.grid_levels::<D>(&s.domain)
                .expect("refinement levels were checked when the scene was validated")
        });
        Self {
            boundaries: Boundaries::new(
                &s.domain.walls,
                &crate::scene::held_bodies::obstacles_with_held(s, &v.materials),
                domain_cells,
            ),
            grid,
            particles,
            settings,
            bins,
            reorder: Reorder::new(n),
            clock: Default::default(),
            reference,
            fields,
            staging,
            scene_json: v.json.clone(),
            stage_tag: serde_json::Value::Null,
            name: s.name.clone(),
            time: 0.0,
            chosen_dt: 0.0,
            steps: 0,
            kinematics: KinematicStats::default(),
            stresses: StressStats::default(),
            ledger: Default::default(),
            energy0: 0.0,
            surface_energy: 0.0,
            // The implicit mode averages over its own patches (`implicit/fbar.rs`).
            volume_average: (fbar && !implicit).then(|| VolumeAverage::new(grid_nodes)),
            physics,
            interpolation: Interpolation::default(),
            needs_interpolation,
            group_views,
            report: PhysicsReport::default(),
            stress_scratch: StressScratch::new(
                D == 2
                    && s.solver.free_strain_2d
                        == crate::scene::FreeStrain2d::GeneralizedPlaneStrain,
            ),
            physics_dt: f64::INFINITY,
            relax_time: None,
            inflow,
            sort_counter: 0,
            contact,
            mode: Some(super::mode::for_scene(s.solver.mechanics, fbar, refined)),
            _kernel: std::marker::PhantomData,
        }
    }
}
