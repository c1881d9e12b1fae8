//! The hyper-reduced time stepper. Each step it
//! 1. evaluates the map g(X, q) at the sampled particles and at the particles whose kernel
//!    stencils overlap theirs (the quadrature neighbourhood),
//! 2. does the ordinary MPM update for those particles only: stress from the scene's
//!    material plugins with F = ∂g/∂X, P2G, the core's grid update with the scene's walls
//!    and obstacles, and G2P to the sampled particles,
//! 3. projects the sampled particles' new positions and velocities back onto the map by
//!    least squares through the Jacobian ∂g/∂q (Gauss–Newton for the neural map), giving q
//!    and q̇.
//!
//! Frames evaluate the map at every particle of the scene, whatever its resolution, and
//! go to the same result layout as a full run.

use crate::map::PointMap;
use crate::{Model, ModelKind, RomError};
use mpm_core::kernels::Kernel;
use mpm_core::material::{BatchStats, Material, StateSlices, StressBatch};
use mpm_core::math::{Matrix, Vector, determinant, inverse, vector_from_slice};
use mpm_core::output::{
    Diagnostic, FRAME_DIAGNOSTICS, FieldInfo, Frame, Metrics, Outcome, OutputSink, RunInfo,
};
use mpm_core::scene::{Transfer, ValidatedScene};
use mpm_core::solver::grid_update::{GridParams, update_grid};
use mpm_core::solver::stencil::{Stencil, stencil_fits};
use mpm_core::solver::{
    Control, DimensionDispatch, Progress, RunObserver, Simulation, SimulationVisitor, dispatch,
    stable_time_step,
};
use rayon::prelude::*;
use std::time::Instant;

/// Settings of `mpm rom run`.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Sampled particles N at which the MPM update is done.
    pub samples: usize,
    /// Multiplies the scene's time step (1: the full-order step).
    pub time_step_scale: f64,
    /// Extra reach, in cells, of the candidate neighbourhood around each sample beyond the
    /// kernel's, for particles that come closer as the body deforms.
    pub margin: f64,
    /// Gauss–Newton iterations of the projection (the linear map needs one).
    pub projection_iterations: usize,
    /// Sample only particles at least a cell inside the body (see [`interior_particles`]).
    pub interior_samples: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            samples: 32,
            time_step_scale: 1.0,
            margin: 1.0,
            projection_iterations: 3,
            interior_samples: true,
        }
    }
}

/// Output fields a reduced run can write.
pub const REDUCED_FIELDS: &[&str] = &["x", "v", "F", "J", "stress", "mass", "volume", "material"];

/// Runs `scene` with `model` and writes its frames to `sink`. The metrics carry
/// `rom.samples`, `rom.latent`, `rom.candidates` and `rom.quadrature_points` (mean per step)
/// under `physics`.
pub fn run_reduced(
    scene: &ValidatedScene,
    model: &Model,
    options: &RunOptions,
    sink: &mut dyn OutputSink,
    observer: &mut dyn RunObserver,
) -> Result<Metrics, RomError> {
    model.check_scene(scene)?;
    let dim = model.info.dimension;
    if options.samples == 0 || options.samples * dim < model.info.latent {
        return Err(RomError::Option(format!(
            "--samples {} gives {} equations for {} coordinates; use at least {}",
            options.samples,
            options.samples * dim,
            model.info.latent,
            model.info.latent.div_ceil(dim)
        )));
    }
    if options.samples > scene.particle_count() {
        return Err(RomError::Option(format!(
            "--samples {} exceeds the scene's {} particles",
            options.samples,
            scene.particle_count()
        )));
    }
    if !(options.time_step_scale > 0.0 && options.time_step_scale <= 100.0) {
        return Err(RomError::Option(format!(
            "--dt-scale must be in (0, 100], got {}",
            options.time_step_scale
        )));
    }
    if !(options.margin >= 0.0 && options.margin <= 10.0) {
        return Err(RomError::Option(format!(
            "--margin must be in [0, 10] cells, got {}",
            options.margin
        )));
    }
    for (i, name) in scene.scene.output.fields.iter().enumerate() {
        if !REDUCED_FIELDS.contains(&name.as_str()) {
            return Err(RomError::Mismatch {
                path: format!("output.fields[{i}]"),
                message: format!(
                    "field `{name}` is not available from a reduced run (available: {})",
                    REDUCED_FIELDS.join(", ")
                ),
            });
        }
    }
    struct Visit<'a> {
        scene: &'a ValidatedScene,
        model: &'a Model,
        options: &'a RunOptions,
        sink: &'a mut dyn OutputSink,
        observer: &'a mut dyn RunObserver,
    }
    impl SimulationVisitor for Visit<'_> {
        type Output = Result<Metrics, RomError>;
        fn visit<const D: usize, K: Kernel>(self, sim: Simulation<D, K>) -> Self::Output
        where
            dyn Material: DimensionDispatch<D>,
        {
            let mut run = Reduced::<D, K>::new(sim, self.scene, self.model, self.options)?;
            run.run(self.scene, self.sink, self.observer)
        }
    }
    dispatch(
        scene,
        Visit {
            scene,
            model,
            options,
            sink,
            observer,
        },
    )
}

/// Fixed settings of a reduced run, from the scene.
struct Settings<const D: usize> {
    gravity: Vector<D>,
    damping: f64,
    cfl: f64,
    fixed_dt: Option<f64>,
    end_time: f64,
    frames: u32,
    affine: bool,
    mls: bool,
    inertia: f64,
    min_dt: f64,
}

/// Per-step figures.
#[derive(Clone, Copy, Debug, Default)]
struct StepStats {
    max_speed: f64,
    max_wave_speed: f64,
    min_det_f: f64,
}

struct Reduced<'m, const D: usize, K: Kernel> {
    sim: Simulation<D, K>,
    boundaries: mpm_core::boundary::Boundaries<D>,
    settings: Settings<D>,
    map: Box<dyn PointMap + 'm>,
    linear: bool,
    latent: usize,
    iterations: usize,
    q: Vec<f64>,
    q_rate: Vec<f64>,
    q_next: Vec<f64>,
    samples: Vec<u32>,
    candidates: Vec<u32>,
    // Step scratch, sized once.
    candidate_x: Vec<f64>,
    base_mark: Vec<u32>,
    epoch: u32,
    quad: Vec<u32>,
    quad_x: Vec<Vector<D>>,
    quad_v: Vec<Vector<D>>,
    quad_f: Vec<Matrix<D>>,
    quad_c: Vec<Matrix<D>>,
    quad_stress: Vec<Matrix<D>>,
    quad_volume0: Vec<f64>,
    flat_f: Vec<f64>,
    flat_rate: Vec<f64>,
    flat_v: Vec<f64>,
    p2g: Vec<f64>,
    p2g_base: Vec<usize>,
    sample_x: Vec<f64>,
    sample_target: Vec<f64>,
    sample_v: Vec<f64>,
    sample_jac: Vec<f64>,
    normal: Vec<f64>,
    rhs: Vec<f64>,
    // Frame scratch over every particle.
    all: Vec<u32>,
    all_x: Vec<f64>,
    all_flat_v: Vec<f64>,
    all_flat_f: Vec<f64>,
    all_f: Vec<Matrix<D>>,
    all_stress: Vec<Matrix<D>>,
    all_v: Vec<Vector<D>>,
    fields: Vec<FieldInfo>,
    staging: Vec<Vec<f64>>,
    quadrature_total: f64,
    quadrature_max: usize,
    stats: StepStats,
    frame_strain: f64,
}

impl<'m, const D: usize, K: Kernel> Reduced<'m, D, K>
where
    dyn Material: DimensionDispatch<D>,
{
    fn new(
        sim: Simulation<D, K>,
        scene: &ValidatedScene,
        model: &'m Model,
        options: &RunOptions,
    ) -> Result<Self, RomError> {
        let s = &scene.scene;
        let n = sim.particles.len();
        let reference: Vec<f64> = sim
            .particles
            .position
            .iter()
            .flat_map(|x| x.iter().copied())
            .collect();
        let map = model.map().bind(&reference)?;
        let latent = model.info.latent;
        let dx = sim.grid.dx;
        let eligible = if options.interior_samples {
            interior_particles::<D>(&sim.particles.position, dx)
        } else {
            (0..n).collect()
        };
        let samples =
            farthest_point_samples::<D>(&sim.particles.position, &eligible, options.samples);
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
            stats: StepStats::default(),
            frame_strain: 0.0,
            sim,
        })
    }

    /// Initial q (the model's undeformed code, refined onto the scene's positions at the
    /// samples) and q̇ (least squares of the initial velocities of every particle).
    fn initialise(&mut self) -> Result<(), RomError> {
        for (k, &p) in self.samples.iter().enumerate() {
            let x = self.sim.particles.position[p as usize];
            self.sample_target[k * D..(k + 1) * D].copy_from_slice(x.as_slice());
        }
        self.project_positions()?;
        let n = self.all.len();
        let l = self.latent;
        // Once per run: the Jacobian of every particle, to fit q̇ to the initial velocities.
        let mut jacobians = vec![0.0; n * D * l];
        self.map.jacobians(&self.q, &self.all, &mut jacobians)?;
        self.normal.fill(0.0);
        self.rhs.fill(0.0);
        for p in 0..n {
            let j = &jacobians[p * D * l..(p + 1) * D * l];
            let v = self.sim.particles.velocity[p];
            accumulate_normal(j, v.as_slice(), D, l, &mut self.normal, &mut self.rhs);
        }
        solve_regularised(&mut self.normal, &mut self.rhs, l);
        self.q_rate.copy_from_slice(&self.rhs);
        Ok(())
    }

    /// Gauss–Newton fit of q to `sample_target` (one iteration is exact for the linear map).
    fn project_positions(&mut self) -> Result<(), RomError> {
        let l = self.latent;
        self.q_next.copy_from_slice(&self.q);
        let iterations = if self.linear { 1 } else { self.iterations };
        for _ in 0..iterations {
            self.map
                .positions(&self.q_next, &self.samples, &mut self.sample_x)?;
            self.map
                .jacobians(&self.q_next, &self.samples, &mut self.sample_jac)?;
            self.normal.fill(0.0);
            self.rhs.fill(0.0);
            let mut residual = [0.0; 3];
            for k in 0..self.samples.len() {
                for (d, r) in residual.iter_mut().take(D).enumerate() {
                    *r = self.sample_target[k * D + d] - self.sample_x[k * D + d];
                }
                let j = &self.sample_jac[k * D * l..(k + 1) * D * l];
                accumulate_normal(j, &residual[..D], D, l, &mut self.normal, &mut self.rhs);
            }
            solve_regularised(&mut self.normal, &mut self.rhs, l);
            for (q, dq) in self.q_next.iter_mut().zip(&self.rhs) {
                *q += dq;
            }
        }
        if self.q_next.iter().any(|v| !v.is_finite()) {
            return Err(RomError::Option(
                "the projection onto the map failed (q not finite)".into(),
            ));
        }
        self.q.copy_from_slice(&self.q_next);
        Ok(())
    }

    /// Least-squares q̇ from the sampled particles' velocities `sample_v`.
    fn project_velocities(&mut self) -> Result<(), RomError> {
        let l = self.latent;
        if !self.linear {
            self.map
                .jacobians(&self.q, &self.samples, &mut self.sample_jac)?;
        }
        self.normal.fill(0.0);
        self.rhs.fill(0.0);
        for k in 0..self.samples.len() {
            let j = &self.sample_jac[k * D * l..(k + 1) * D * l];
            let v = &self.sample_v[k * D..(k + 1) * D];
            accumulate_normal(j, v, D, l, &mut self.normal, &mut self.rhs);
        }
        solve_regularised(&mut self.normal, &mut self.rhs, l);
        self.q_rate.copy_from_slice(&self.rhs);
        Ok(())
    }

    fn half_size(&self, p: usize) -> f64 {
        if K::USES_PARTICLE_SIZE {
            self.sim.particles.half_size[p]
        } else {
            0.0
        }
    }

    /// One reduced step of `dt` ending at `time_end`. Returns a diagnostic when the step
    /// cannot go on (a sample left the grid, a particle inverted).
    fn step(&mut self, dt: f64, time_end: f64) -> Result<Option<Diagnostic>, RomError> {
        let grid_nodes = self.sim.grid.nodes;
        // 1. Mark the base nodes whose stencils meet a sample's stencil.
        self.map
            .positions(&self.q, &self.samples, &mut self.sample_x)?;
        self.epoch = self.epoch.wrapping_add(1).max(1);
        let span = K::SPAN as isize;
        for k in 0..self.samples.len() {
            let x: Vector<D> = vector_from_slice(&self.sample_x[k * D..]);
            let p = self.samples[k] as usize;
            if !stencil_fits::<D, K>(&self.sim.grid, &x, self.half_size(p)) {
                return Ok(Some(diagnostic(
                    p,
                    "x",
                    x.norm(),
                    "a sampled particle left the grid",
                )));
            }
            let mut lo = [0usize; 3];
            let mut hi = [0usize; 3];
            for d in 0..D {
                let xi = (x[d] - self.sim.grid.origin[d]) * self.sim.grid.inv_dx;
                let base = K::weights(xi, self.half_size(p)).base;
                lo[d] = (base - (span - 1)).max(0) as usize;
                hi[d] = ((base + span - 1) as usize).min(grid_nodes[d] - 1);
            }
            for i in lo[0]..=hi[0] {
                for j in lo[1]..=hi[1] {
                    for kk in lo[2]..=hi[2] {
                        let index = self.sim.grid.index([i, j, kk]);
                        self.base_mark[index] = self.epoch;
                    }
                }
            }
        }
        // 2. The quadrature particles: candidates whose base node is marked.
        self.map
            .positions(&self.q, &self.candidates, &mut self.candidate_x)?;
        self.quad.clear();
        self.quad_x.clear();
        for (k, &p) in self.candidates.iter().enumerate() {
            let x: Vector<D> = vector_from_slice(&self.candidate_x[k * D..]);
            let half = self.half_size(p as usize);
            if !stencil_fits::<D, K>(&self.sim.grid, &x, half) {
                continue;
            }
            let mut base = [0usize; 3];
            for d in 0..D {
                let xi = (x[d] - self.sim.grid.origin[d]) * self.sim.grid.inv_dx;
                base[d] = K::weights(xi, half).base as usize;
            }
            if self.base_mark[self.sim.grid.index(base)] == self.epoch {
                self.quad.push(p);
                self.quad_x.push(x);
            }
        }
        let nq = self.quad.len();
        self.quadrature_total += nq as f64;
        self.quadrature_max = self.quadrature_max.max(nq);
        // 3. Kinematics from the map: F, velocity and affine velocity of each.
        self.map
            .gradients(&self.q, &self.quad, &mut self.flat_f[..nq * D * D])?;
        self.map.velocities(
            &self.q,
            &self.q_rate,
            &self.quad,
            &mut self.flat_v[..nq * D],
        )?;
        let affine = self.settings.affine;
        if affine {
            self.map.gradient_rates(
                &self.q,
                &self.q_rate,
                &self.quad,
                &mut self.flat_rate[..nq * D * D],
            )?;
        }
        let (flat_f, flat_v, flat_rate) = (&self.flat_f, &self.flat_v, &self.flat_rate);
        let volume0 = &self.sim.particles.volume0;
        let quad = &self.quad;
        let (min_det_f, max_speed) = self.quad_f[..nq]
            .par_iter_mut()
            .zip(self.quad_v[..nq].par_iter_mut())
            .zip(self.quad_c[..nq].par_iter_mut())
            .zip(self.quad_volume0[..nq].par_iter_mut())
            .enumerate()
            .map(|(k, (((f, v), c), v0))| {
                *f = matrix_from_rows::<D>(&flat_f[k * D * D..]);
                *v = vector_from_slice(&flat_v[k * D..]);
                *v0 = volume0[quad[k] as usize];
                if affine {
                    let rate = matrix_from_rows::<D>(&flat_rate[k * D * D..]);
                    *c = inverse(f).map_or_else(Matrix::<D>::zeros, |fi| rate * fi);
                }
                (determinant(f), v.norm())
            })
            .reduce(
                || (f64::INFINITY, 0.0f64),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            );
        let mut stats = StepStats {
            min_det_f,
            max_speed,
            ..StepStats::default()
        };
        if stats.min_det_f.is_nan() || stats.min_det_f <= 0.0 {
            return Ok(Some(diagnostic(
                0,
                "J",
                stats.min_det_f,
                "the map inverted a quadrature particle (det F <= 0)",
            )));
        }
        // 4. Stress from the scene's materials, by material batch.
        let mut batch_stats = BatchStats::default();
        for group in &self.sim.particles.groups {
            let a = self
                .quad
                .partition_point(|&p| (p as usize) < group.range.start);
            let b = self
                .quad
                .partition_point(|&p| (p as usize) < group.range.end);
            batch_stats = batch_stats.merge(update_stress_parallel::<D>(
                &*group.material,
                dt,
                &self.quad_f[a..b],
                &self.quad_volume0[a..b],
                &mut self.quad_stress[a..b],
            ));
        }
        stats.max_wave_speed = batch_stats.max_wave_speed;
        // 5. P2G over the quadrature particles: each particle's stencil contributions are
        // computed in parallel into a buffer, then added to the grid in one pass.
        let span_z = if D == 3 { K::SPAN } else { 1 };
        let per = K::SPAN * K::SPAN * span_z * (1 + D);
        if self.p2g.len() < nq * per {
            self.p2g.resize(nq * per, 0.0);
            self.p2g_base.resize(nq, 0);
        }
        let grid = &mut self.sim.grid;
        let (dx, inv_dx, stride) = (grid.dx, grid.inv_dx, grid.stride);
        let gravity = self.settings.gravity;
        let (mls, inertia) = (self.settings.mls, self.settings.inertia);
        let particles = &self.sim.particles;
        let (quad_x, quad_v, quad_c) = (&self.quad_x, &self.quad_v, &self.quad_c);
        let (quad_f, quad_stress, quad_volume0) =
            (&self.quad_f, &self.quad_stress, &self.quad_volume0);
        {
            let grid = &*grid;
            self.p2g[..nq * per]
                .par_chunks_mut(per)
                .zip(self.p2g_base[..nq].par_iter_mut())
                .enumerate()
                .for_each(|(k, (buffer, base))| {
                    let p = quad[k] as usize;
                    let half = if K::USES_PARTICLE_SIZE {
                        particles.half_size[p]
                    } else {
                        0.0
                    };
                    let stencil = Stencil::<D>::new::<K>(grid, &quad_x[k], half);
                    *base = stencil.base_index;
                    let m = particles.mass[p];
                    let mv = (quad_v[k] + gravity * dt) * m;
                    let volume = quad_volume0[k] * determinant(&quad_f[k]);
                    let mut affine_momentum = Matrix::<D>::zeros();
                    if affine {
                        affine_momentum += quad_c[k] * (m * dx);
                    }
                    let mut force = Matrix::<D>::zeros();
                    if mls {
                        affine_momentum -=
                            quad_stress[k] * (dt * volume / (inertia * dx * dx) * dx);
                    } else {
                        force = quad_stress[k] * (-volume * inv_dx * dt);
                    }
                    let mut t = 0;
                    stencil.for_each::<K>(&stride, |_, w, grad, dpos| {
                        buffer[t] = w * m;
                        let add = (mv + affine_momentum * dpos) * w + force * grad;
                        buffer[t + 1..t + 1 + D].copy_from_slice(add.as_slice());
                        t += 1 + D;
                    });
                });
        }
        grid.mass.fill(0.0);
        grid.momentum.fill(Vector::<D>::zeros());
        for k in 0..nq {
            let base = self.p2g_base[k];
            let buffer = &self.p2g[k * per..(k + 1) * per];
            let mut t = 0;
            for a in 0..K::SPAN {
                for b in 0..K::SPAN {
                    for c in 0..span_z {
                        let i = base + a * stride[0] + b * stride[1] + c;
                        grid.mass[i] += buffer[t];
                        grid.momentum[i] +=
                            Vector::<D>::from_column_slice(&buffer[t + 1..t + 1 + D]);
                        t += 1 + D;
                    }
                }
            }
        }
        // 6. The core's grid update: forces, damping, walls and obstacles.
        update_grid(
            grid,
            &self.boundaries,
            GridParams {
                dt,
                forces: true,
                flip: false,
                damping: self.settings.damping,
                time: time_end,
            },
        );
        // 7. G2P to the sampled particles.
        for k in 0..self.samples.len() {
            let p = self.samples[k] as usize;
            let x: Vector<D> = vector_from_slice(&self.sample_x[k * D..]);
            let half = if K::USES_PARTICLE_SIZE {
                self.sim.particles.half_size[p]
            } else {
                0.0
            };
            let stencil = Stencil::<D>::new::<K>(grid, &x, half);
            let mut v = Vector::<D>::zeros();
            let velocity = &grid.momentum;
            stencil.for_each::<K>(&stride, |i, w, _, _| v += velocity[i] * w);
            let x_new = x + v * dt;
            self.sample_target[k * D..(k + 1) * D].copy_from_slice(x_new.as_slice());
            self.sample_v[k * D..(k + 1) * D].copy_from_slice(v.as_slice());
            stats.max_speed = stats.max_speed.max(v.norm());
        }
        // 8. Back onto the map.
        self.project_positions()?;
        self.project_velocities()?;
        self.stats = stats;
        Ok(None)
    }

    /// Evaluates the map at every particle and fills the output buffers; returns the
    /// frame's diagnostics.
    fn evaluate_frame(&mut self, dt: f64, steps: u64) -> Result<[f64; 10], RomError> {
        let n = self.all.len();
        self.map.positions(&self.q, &self.all, &mut self.all_x)?;
        self.map
            .velocities(&self.q, &self.q_rate, &self.all, &mut self.all_flat_v)?;
        self.map
            .gradients(&self.q, &self.all, &mut self.all_flat_f)?;
        let particles = &self.sim.particles;
        let (mut kinetic, mut gravity_energy, mut max_speed) = (0.0, 0.0, 0.0f64);
        let mut momentum = Vector::<D>::zeros();
        let mut min_det = f64::INFINITY;
        for p in 0..n {
            let v: Vector<D> = vector_from_slice(&self.all_flat_v[p * D..]);
            let x: Vector<D> = vector_from_slice(&self.all_x[p * D..]);
            let m = particles.mass[p];
            kinetic += 0.5 * m * v.norm_squared();
            gravity_energy -= m * self.settings.gravity.dot(&x);
            max_speed = max_speed.max(v.norm());
            momentum += v * m;
            self.all_v[p] = v;
            self.all_f[p] = matrix_from_rows::<D>(&self.all_flat_f[p * D * D..]);
            min_det = min_det.min(determinant(&self.all_f[p]));
        }
        let mut strain = BatchStats::default();
        for group in &particles.groups {
            let r = group.range.clone();
            strain = strain.merge(update_stress_parallel::<D>(
                &*group.material,
                dt.max(0.0),
                &self.all_f[r.clone()],
                &particles.volume0[r.clone()],
                &mut self.all_stress[r],
            ));
        }
        self.frame_strain = strain.strain_energy;
        if self.stats.max_wave_speed == 0.0 {
            self.stats.max_wave_speed = strain.max_wave_speed;
        }
        for (field, out) in self.fields.iter().zip(self.staging.iter_mut()) {
            let c = field.components();
            for p in 0..n {
                let o = particles.id[p] as usize * c;
                match field.name.as_str() {
                    "x" => out[o..o + D].copy_from_slice(&self.all_x[p * D..(p + 1) * D]),
                    "v" => out[o..o + D].copy_from_slice(self.all_v[p].as_slice()),
                    "F" | "stress" => {
                        let m = if field.name == "F" {
                            &self.all_f[p]
                        } else {
                            &self.all_stress[p]
                        };
                        for r in 0..D {
                            for col in 0..D {
                                out[o + r * D + col] = m[(r, col)];
                            }
                        }
                    }
                    "J" => out[o] = determinant(&self.all_f[p]),
                    "volume" => out[o] = determinant(&self.all_f[p]) * particles.volume0[p],
                    "mass" => out[o] = particles.mass[p],
                    _ => {}
                }
            }
            if field.name == "material" {
                for (g, group) in particles.groups.iter().enumerate() {
                    for p in group.range.clone() {
                        out[particles.id[p] as usize] = g as f64;
                    }
                }
            }
        }
        let total = kinetic + strain.strain_energy + gravity_energy;
        Ok([
            steps as f64,
            dt,
            kinetic,
            strain.strain_energy,
            gravity_energy,
            total,
            max_speed,
            min_det,
            momentum.norm(),
            0.0,
        ])
    }

    fn write_frame(
        &mut self,
        sink: &mut dyn OutputSink,
        index: usize,
        time: f64,
        dt: f64,
        steps: u64,
    ) -> Result<[f64; 10], RomError> {
        let diagnostics = self.evaluate_frame(dt, steps)?;
        debug_assert_eq!(diagnostics.len(), FRAME_DIAGNOSTICS.len());
        sink.write_frame(&Frame {
            index,
            time,
            values: &self.staging,
            diagnostics: &diagnostics,
        })?;
        Ok(diagnostics)
    }

    fn run(
        &mut self,
        scene: &ValidatedScene,
        sink: &mut dyn OutputSink,
        observer: &mut dyn RunObserver,
    ) -> Result<Metrics, RomError> {
        let n = self.all.len();
        let start = Instant::now();
        self.initialise()?;
        sink.begin(&RunInfo {
            name: &scene.scene.name,
            dimension: D,
            particles: n,
            fields: &self.fields,
            scene: &scene.json,
        })?;
        let end_time = self.settings.end_time;
        let frame_dt = end_time / self.settings.frames as f64;
        let eps = 1e-9 * frame_dt;
        let first = self.write_frame(sink, 0, 0.0, 0.0, 0)?;
        let mut frame = 1usize;
        let (mut time, mut steps) = (0.0f64, 0u64);
        let mut min_det = first[7];
        let mut max_speed = first[6];
        let mut max_momentum = first[8];
        let mut outcome = Outcome::Finished;
        let mut diagnostic = None;
        let mut speed = first[6];
        while time < end_time - eps {
            let stable = stable_time_step(self.sim.grid.dx, speed, self.stats.max_wave_speed);
            let mut dt = self.settings.fixed_dt.unwrap_or(self.settings.cfl * stable);
            if dt < self.settings.min_dt || !dt.is_finite() {
                outcome = Outcome::Stopped;
                diagnostic = Some(diagnostic_at(
                    steps,
                    time,
                    diagnostic_plain("dt", dt, "the time step fell below stop.min_dt"),
                ));
                break;
            }
            let next_frame_time = (frame as f64 * frame_dt).min(end_time);
            if time + dt > next_frame_time - eps {
                dt = next_frame_time - time;
            }
            if let Some(d) = self.step(dt, time + dt)? {
                outcome = Outcome::Stopped;
                diagnostic = Some(diagnostic_at(steps, time, d));
                break;
            }
            time += dt;
            steps += 1;
            speed = self.stats.max_speed;
            min_det = min_det.min(self.stats.min_det_f);
            max_speed = max_speed.max(speed);
            if time >= next_frame_time - eps {
                let d = self.write_frame(sink, frame, time, dt, steps)?;
                max_momentum = max_momentum.max(d[8]);
                min_det = min_det.min(d[7]);
                frame += 1;
            }
            let progress = Progress {
                step: steps,
                time,
                end_time,
                dt,
                wall_seconds: start.elapsed().as_secs_f64(),
            };
            if observer.progress(&progress) == Control::Cancel {
                outcome = Outcome::Cancelled;
                break;
            }
        }
        let wall = start.elapsed().as_secs_f64();
        let mut physics = std::collections::BTreeMap::new();
        physics.insert("rom.samples".to_string(), self.samples.len() as f64);
        physics.insert("rom.latent".to_string(), self.latent as f64);
        physics.insert("rom.candidates".to_string(), self.candidates.len() as f64);
        physics.insert(
            "rom.quadrature_points".to_string(),
            self.quadrature_total / steps.max(1) as f64,
        );
        physics.insert(
            "rom.max_quadrature_points".to_string(),
            self.quadrature_max as f64,
        );
        let metrics = Metrics {
            outcome: Some(outcome),
            wall_seconds: wall,
            steps,
            simulated_time: time,
            particles: n,
            particle_steps_per_second: if wall > 0.0 {
                steps as f64 * n as f64 / wall
            } else {
                0.0
            },
            min_det_f: min_det,
            max_speed,
            max_momentum,
            frames: frame,
            threads: rayon::current_num_threads(),
            diagnostic,
            physics,
            ..Metrics::default()
        };
        sink.finish(&metrics)?;
        Ok(metrics)
    }
}

/// A diagnostic without step and time (filled in by [`diagnostic_at`]).
fn diagnostic(particle: usize, field: &str, value: f64, message: &str) -> Diagnostic {
    Diagnostic {
        step: 0,
        time: 0.0,
        particle: Some(particle),
        field: field.into(),
        value,
        message: message.into(),
    }
}

fn diagnostic_plain(field: &str, value: f64, message: &str) -> Diagnostic {
    Diagnostic {
        particle: None,
        ..diagnostic(0, field, value, message)
    }
}

fn diagnostic_at(step: u64, time: f64, d: Diagnostic) -> Diagnostic {
    Diagnostic { step, time, ..d }
}

/// Builds a matrix from `D·D` row-major numbers.
#[inline(always)]
fn matrix_from_rows<const D: usize>(s: &[f64]) -> Matrix<D> {
    Matrix::<D>::from_fn(|r, c| s[r * D + c])
}

/// Adds `Jᵀ J` and `Jᵀ r` of one point (J row-major `dim × latent`) to the normal equations.
#[inline]
fn accumulate_normal(
    j: &[f64],
    r: &[f64],
    dim: usize,
    latent: usize,
    normal: &mut [f64],
    rhs: &mut [f64],
) {
    for d in 0..dim {
        let row = &j[d * latent..(d + 1) * latent];
        for a in 0..latent {
            rhs[a] += row[a] * r[d];
            for b in 0..latent {
                normal[a * latent + b] += row[a] * row[b];
            }
        }
    }
}

/// Solves `(A + εI) x = b` in place (x in `b`) for a symmetric positive semi-definite `A`,
/// ε a tiny multiple of its mean diagonal so near-singular systems stay solvable.
fn solve_regularised(a: &mut [f64], b: &mut [f64], n: usize) {
    let mean = (0..n).map(|i| a[i * n + i]).sum::<f64>() / n as f64;
    let eps = 1e-12 * mean.max(1e-300);
    for i in 0..n {
        a[i * n + i] += eps;
    }
    // Cholesky: A = L Lᵀ, L stored in the lower triangle.
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        let d = d.max(eps).sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
}

/// Calls a material's batch update on chunks of particles in parallel.
fn update_stress_parallel<const D: usize>(
    material: &(dyn Material + 'static),
    dt: f64,
    f: &[Matrix<D>],
    volume0: &[f64],
    stress: &mut [Matrix<D>],
) -> BatchStats
where
    dyn Material: DimensionDispatch<D>,
{
    const CHUNK: usize = 1024;
    stress
        .par_chunks_mut(CHUNK)
        .zip(f.par_chunks(CHUNK))
        .zip(volume0.par_chunks(CHUNK))
        .map(|((stress, f), volume0)| {
            <dyn Material as DimensionDispatch<D>>::update(
                material,
                StressBatch {
                    dt,
                    deformation_gradient: f,
                    velocity_gradient: &[],
                    volume0,
                    stress,
                    state: StateSlices {
                        fields: Default::default(),
                    },
                    shared: [&[]; mpm_core::material::MAX_SHARED_READS],
                    plastic_work: &mut [],
                },
            )
        })
        .reduce(BatchStats::default, BatchStats::merge)
}

/// Particles at least a cell inside the body: their 3^D neighbouring cells (of size `dx`,
/// in the reference configuration) hold at least 90% of the most any particle sees. Their
/// grid nodes are full, so the accelerations sampled there are not those of the sparsely
/// filled surface nodes; the outermost layer is left out. Every particle when none is.
pub fn interior_particles<const D: usize>(positions: &[Vector<D>], dx: f64) -> Vec<usize> {
    use std::collections::HashMap;
    let cell = |x: &Vector<D>| -> [i64; 3] {
        let mut c = [0i64; 3];
        for d in 0..D {
            c[d] = (x[d] / dx).floor() as i64;
        }
        c
    };
    let mut counts: HashMap<[i64; 3], usize> = HashMap::new();
    for x in positions {
        *counts.entry(cell(x)).or_default() += 1;
    }
    let reach = |c: [i64; 3]| -> usize {
        let mut total = 0;
        let z = if D == 3 { -1..=1 } else { 0..=0 };
        for i in -1..=1 {
            for j in -1..=1 {
                for k in z.clone() {
                    total += counts
                        .get(&[c[0] + i, c[1] + j, c[2] + k])
                        .copied()
                        .unwrap_or(0);
                }
            }
        }
        total
    };
    let seen: Vec<usize> = positions.iter().map(|x| reach(cell(x))).collect();
    let most = seen.iter().copied().max().unwrap_or(0);
    let inside: Vec<usize> = (0..positions.len())
        .filter(|&p| seen[p] * 10 >= most * 9)
        .collect();
    if inside.is_empty() {
        (0..positions.len()).collect()
    } else {
        inside
    }
}

/// `count` particles spread over `eligible` particles by farthest-point sampling in the
/// reference configuration, starting from the one nearest the centroid; sorted by index.
pub fn farthest_point_samples<const D: usize>(
    positions: &[Vector<D>],
    eligible: &[usize],
    count: usize,
) -> Vec<u32> {
    let n = eligible.len();
    if n == 0 || count == 0 {
        return Vec::new();
    }
    let centroid = eligible
        .iter()
        .fold(Vector::<D>::zeros(), |a, &p| a + positions[p])
        / n as f64;
    let first = (0..n)
        .min_by(|&a, &b| {
            (positions[eligible[a]] - centroid)
                .norm_squared()
                .total_cmp(&(positions[eligible[b]] - centroid).norm_squared())
        })
        .unwrap_or(0);
    let mut distance = vec![f64::INFINITY; n];
    let mut chosen = vec![eligible[first] as u32];
    let mut last = first;
    while chosen.len() < count.min(n) {
        let from = positions[eligible[last]];
        let next = distance
            .par_iter_mut()
            .zip(eligible.par_iter())
            .enumerate()
            .map(|(i, (d, &p))| {
                *d = d.min((positions[p] - from).norm_squared());
                (i, *d)
            })
            .reduce(
                || (usize::MAX, f64::NEG_INFINITY),
                |a, b| {
                    if b.1 > a.1 || (b.1 == a.1 && b.0 < a.0) {
                        b
                    } else {
                        a
                    }
                },
            );
        last = next.0;
        chosen.push(eligible[last] as u32);
    }
    chosen.sort_unstable();
    chosen.dedup();
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regularised_solve_matches_a_known_solution() {
        let mut a = vec![4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let x = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| a[i * 3 + j] * x[j]).sum())
            .collect();
        solve_regularised(&mut a, &mut b, 3);
        for (got, want) in b.iter().zip(x) {
            assert!((got - want).abs() < 1e-10, "{b:?}");
        }
    }

    #[test]
    fn samples_spread_over_the_interior() {
        // A 10 x 10 lattice of spacing 0.5 in cells of 1: the outermost ring is not interior.
        let positions: Vec<Vector<2>> = (0..100)
            .map(|k| Vector::<2>::new(0.25 + 0.5 * (k / 10) as f64, 0.25 + 0.5 * (k % 10) as f64))
            .collect();
        let inside = interior_particles::<2>(&positions, 1.0);
        assert!(inside.len() < 100 && inside.len() >= 16, "{}", inside.len());
        let samples = farthest_point_samples::<2>(&positions, &inside, 4);
        assert_eq!(samples.len(), 4);
        // Four samples over a square spread to its four quadrants.
        let mut quadrants = [false; 4];
        for s in &samples {
            let x = positions[*s as usize];
            quadrants[(x[0] > 2.5) as usize * 2 + (x[1] > 2.5) as usize] = true;
        }
        assert!(quadrants.iter().all(|q| *q), "{samples:?}");
    }
}
