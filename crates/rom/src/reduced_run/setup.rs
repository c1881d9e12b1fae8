//! The state of a reduced run and its set-up from the scene: the bound map, the samples
//! and their candidate neighbourhood, the run's fixed settings and the scratch buffers of
//! steps and frames, all sized once.

use super::options::{RunOptions, Sampling};
use super::sampling::{farthest_point_samples, interior_particles};
use super::sampling_greedy::{greedy_samples, sample_condition};
use crate::map::PointMap;
use crate::{Model, ModelKind, RomError};
use mpm_core::kernels::Kernel;
use mpm_core::material::Material;
use mpm_core::math::{Matrix, Vector, vector_from_slice};
use mpm_core::output::FieldInfo;
use mpm_core::scene::{Transfer, ValidatedScene};
use mpm_core::solver::{DimensionDispatch, Simulation};
use rayon::prelude::*;

/// Fixed settings of a reduced run, from the scene.
pub(super) struct Settings<const D: usize> {
    pub(super) gravity: Vector<D>,
    pub(super) damping: f64,
    pub(super) cfl: f64,
    pub(super) fixed_dt: Option<f64>,
    pub(super) end_time: f64,
    pub(super) frames: u32,
    pub(super) affine: bool,
    pub(super) mls: bool,
    pub(super) inertia: f64,
    pub(super) min_dt: f64,
}

/// Per-step figures.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct StepStats {
    pub(super) max_speed: f64,
    pub(super) max_wave_speed: f64,
    pub(super) min_det_f: f64,
}

/// A reduced run of dimension `D` with kernel `K`, its map borrowed from the model.
pub(super) struct Reduced<'m, const D: usize, K: Kernel> {
    pub(super) sim: Simulation<D, K>,
    pub(super) boundaries: mpm_core::boundary::Boundaries<D>,
    pub(super) settings: Settings<D>,
    pub(super) map: Box<dyn PointMap + 'm>,
    pub(super) linear: bool,
    pub(super) latent: usize,
    pub(super) iterations: usize,
    pub(super) q: Vec<f64>,
    pub(super) q_rate: Vec<f64>,
    pub(super) q_next: Vec<f64>,
    pub(super) samples: Vec<u32>,
    pub(super) candidates: Vec<u32>,
    // Step scratch, sized once.
    pub(super) candidate_x: Vec<f64>,
    pub(super) base_mark: Vec<u32>,
    pub(super) epoch: u32,
    pub(super) quad: Vec<u32>,
    pub(super) quad_x: Vec<Vector<D>>,
    pub(super) quad_v: Vec<Vector<D>>,
    pub(super) quad_f: Vec<Matrix<D>>,
    pub(super) quad_c: Vec<Matrix<D>>,
    pub(super) quad_stress: Vec<Matrix<D>>,
    pub(super) quad_volume0: Vec<f64>,
    pub(super) flat_f: Vec<f64>,
    pub(super) flat_rate: Vec<f64>,
    pub(super) flat_v: Vec<f64>,
    pub(super) p2g: Vec<f64>,
    pub(super) p2g_base: Vec<usize>,
    pub(super) sample_x: Vec<f64>,
    pub(super) sample_target: Vec<f64>,
    pub(super) sample_v: Vec<f64>,
    pub(super) sample_jac: Vec<f64>,
    pub(super) normal: Vec<f64>,
    pub(super) rhs: Vec<f64>,
    // Frame scratch over every particle.
    pub(super) all: Vec<u32>,
    pub(super) all_x: Vec<f64>,
    pub(super) all_flat_v: Vec<f64>,
    pub(super) all_flat_f: Vec<f64>,
    pub(super) all_f: Vec<Matrix<D>>,
    pub(super) all_stress: Vec<Matrix<D>>,
    pub(super) all_v: Vec<Vector<D>>,
    pub(super) fields: Vec<FieldInfo>,
    pub(super) staging: Vec<Vec<f64>>,
    pub(super) quadrature_total: f64,
    pub(super) quadrature_max: usize,
    /// Wall seconds per part of the step and for the frames.
    pub(super) clock: super::stage_clock::RomClock,
    pub(super) stats: StepStats,
    pub(super) frame_strain: f64,
    /// Condition number of the projection's normal matrix at the samples, at the start.
    pub(super) sample_condition: f64,
}

impl<'m, const D: usize, K: Kernel> Reduced<'m, D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    /// Sets the run up: binds the map, picks the samples and their candidates and sizes
    /// the scratch buffers.
    pub(super) fn new(
        sim: Simulation<D, K>,
        scene: &ValidatedScene,
        model: &'m Model,
        options: &RunOptions,
    ) -> Result<Self, RomError> {
        let mut sim = sim;
        // The reduced step writes only around its samples: a sparse grid clears and updates
        // just the blocks it marks (a dense one took half the step at 500,000 particles).
        sim.grid.set_sparse(true);
        let s = &scene.scene;
        let n = sim.particles.len();
        let reference: Vec<f64> = sim
            .particles
            .position
            .iter()
            .flat_map(|x| x.iter().copied())
            .collect();
        let mut map = model.map().bind(&reference)?;
        let latent = model.info.latent;
        let dx = sim.grid.dx;
        let eligible = if options.interior_samples {
            interior_particles::<D>(&sim.particles.position, dx)
        } else {
            (0..n).collect()
        };
        let q0 = &model.info.initial_latent;
        let samples = match options.sampling {
            Sampling::FarthestPoint => {
                farthest_point_samples::<D>(&sim.particles.position, &eligible, options.samples)
            }
            Sampling::Greedy => {
                let which: Vec<u32> = eligible.iter().map(|&p| p as u32).collect();
                let mut jacobians = vec![0.0; which.len() * D * latent];
                map.jacobians(q0, &which, &mut jacobians)?;
                greedy_samples(&jacobians, &eligible, D, latent, options.samples)
            }
        };
        let mut sample_jacobians = vec![0.0; samples.len() * D * latent];
        map.jacobians(q0, &samples, &mut sample_jacobians)?;
        let condition = sample_condition(&sample_jacobians, D, latent);
        // Candidates: particles within the kernel's reach (plus the margin) of a sample in the
        // reference configuration; each step keeps those whose stencil meets a sample's.
        let reach = (K::SPAN as f64 + options.margin) * dx;
        let sample_points: Vec<Vector<D>> = samples
            .iter()
            .map(|&p| sim.particles.position[p as usize])
            .collect();
        let candidates: Vec<u32> = (0..n as u32)
            .into_par_iter()
            .filter(|&p| {
                let x = sim.particles.position[p as usize];
                sample_points
                    .iter()
                    .any(|s| (0..D).all(|d| (x[d] - s[d]).abs() < reach))
            })
            .collect();
        let c = candidates.len();
        let fields: Vec<FieldInfo> = s
            .output
            .fields
            .iter()
            .map(|name| FieldInfo {
                name: name.clone(),
                shape: match name.as_str() {
                    "x" | "v" => vec![D],
                    "F" | "stress" => vec![D, D],
                    _ => vec![],
                },
            })
            .collect();
        let staging = fields
            .iter()
            .map(|f| vec![0.0; f.components() * n])
            .collect();
        let settings = Settings {
            gravity: s
                .solver
                .gravity
                .as_deref()
                .map(vector_from_slice)
                .unwrap_or_else(Vector::<D>::zeros),
            damping: s.solver.damping,
            cfl: s.solver.cfl,
            fixed_dt: s.solver.dt.map(|dt| dt * options.time_step_scale),
            end_time: s.solver.end_time,
            frames: s.output.frames,
            affine: s.solver.transfer == Transfer::Apic,
            mls: s.solver.mls,
            inertia: K::APIC_INERTIA.unwrap_or(0.25),
            min_dt: s.stop.min_dt,
        };
        let cfl = settings.cfl * options.time_step_scale;
        let grid_len = sim.grid.len();
        let ns = samples.len();
        Ok(Self {
            boundaries: sim.boundaries().clone(),
            settings: Settings { cfl, ..settings },
            map,
            linear: model.info.kind == ModelKind::Linear,
            latent,
            iterations: options.projection_iterations.max(1),
            q: model.info.initial_latent.clone(),
            q_rate: vec![0.0; latent],
            q_next: vec![0.0; latent],
            samples,
            candidates,
            candidate_x: vec![0.0; c * D],
            base_mark: vec![0; grid_len],
            epoch: 0,
            quad: Vec::with_capacity(c),
            quad_x: Vec::with_capacity(c),
            quad_v: vec![Vector::<D>::zeros(); c],
            quad_f: vec![Matrix::<D>::identity(); c],
            quad_c: vec![Matrix::<D>::zeros(); c],
            quad_stress: vec![Matrix::<D>::zeros(); c],
            quad_volume0: vec![0.0; c],
            flat_f: vec![0.0; c * D * D],
            flat_rate: vec![0.0; c * D * D],
            flat_v: vec![0.0; c * D],
            p2g: Vec::new(),
            p2g_base: Vec::new(),
            sample_x: vec![0.0; ns * D],
            sample_target: vec![0.0; ns * D],
            sample_v: vec![0.0; ns * D],
            sample_jac: vec![0.0; ns * D * latent],
            normal: vec![0.0; latent * latent],
            rhs: vec![0.0; latent],
            all: (0..n as u32).collect(),
            all_x: vec![0.0; n * D],
            all_flat_v: vec![0.0; n * D],
            all_flat_f: vec![0.0; n * D * D],
            all_f: vec![Matrix::<D>::identity(); n],
            all_stress: vec![Matrix::<D>::zeros(); n],
            all_v: vec![Vector::<D>::zeros(); n],
            fields,
            staging,
            quadrature_total: 0.0,
            quadrature_max: 0,
            clock: Default::default(),
            stats: StepStats::default(),
            frame_strain: 0.0,
            sample_condition: condition,
            sim,
        })
    }
}
