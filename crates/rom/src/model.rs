//! A trained reduced model: which map (linear or neural), what it was trained on, and the
//! checks that a scene is one it can run.

use crate::RomError;
use crate::file::{self, NamedArray};
use crate::map::ReducedMap;
use crate::mode_field::{LinearMap, ModeGrid};
use crate::neural::{NeuralMap, NeuralOptions};
use crate::snapshots::{self, Snapshots};
use mpm_core::scene::{AntiLocking, Mechanics, Transfer, ValidatedScene};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Version of the model file layout.
pub const FORMAT: u32 = 1;

/// The two kinds of reduced map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelKind {
    /// x = X + Σ q_k φ_k(X), POD modes as B-spline fields.
    Linear,
    /// x = g(X, q), a small neural network (trained with candle).
    Neural,
}

/// What the model was trained on, for the record and for checking scenes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainingInfo {
    /// The training stores.
    pub runs: Vec<String>,
    /// Snapshots (frames of all runs).
    pub snapshots: usize,
    /// Particles per snapshot.
    pub particles: usize,
    /// Share of the snapshots' squared displacement the kept POD modes capture.
    pub pod_captured: f64,
    /// Leading POD singular values (at most 32).
    pub singular_values: Vec<f64>,
    /// RMS position misfit of the trained map over all snapshots, relative to the RMS
    /// displacement.
    pub fit_error: f64,
    /// Wall seconds of training.
    pub seconds: f64,
    /// Name of the training scene.
    pub scene: String,
    /// Kernel of the training scene (`solver.kernel`).
    pub kernel: serde_json::Value,
    /// Cell size of the training scene, metres.
    pub cell_size: f64,
    /// Lower and upper corner of the training particles' reference box, metres.
    pub reference_box: [Vec<f64>; 2],
}

/// The description stored in the model file's metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelInfo {
    /// Layout version ([`FORMAT`]).
    pub format: u32,
    /// Linear or neural.
    pub kind: ModelKind,
    /// 2 or 3.
    pub dimension: usize,
    /// Number of generalised coordinates q.
    pub latent: usize,
    /// q of the undeformed state (zero for the linear map).
    pub initial_latent: Vec<f64>,
    /// Training record.
    pub training: TrainingInfo,
    /// Coefficient grid of the linear map.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode_grid: Option<ModeGrid>,
    /// Description of the neural map.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub network: Option<serde_json::Value>,
}

/// The map of a model.
enum MapImpl {
    Linear(LinearMap),
    Neural(NeuralMap),
}

/// A trained reduced model.
pub struct Model {
    /// Its description.
    pub info: ModelInfo,
    map: MapImpl,
}

/// Settings of `mpm rom train`.
#[derive(Clone, Debug)]
pub struct TrainOptions {
    /// Linear or neural.
    pub kind: ModelKind,
    /// Number of generalised coordinates.
    pub latent: usize,
    /// Spacing of the linear map's coefficient grid (default: half the training cell size).
    pub mode_spacing: Option<f64>,
    /// Network settings (neural only).
    pub neural: NeuralOptions,
}

impl Model {
    /// The deformation map.
    pub fn map(&self) -> &dyn ReducedMap {
        match &self.map {
            MapImpl::Linear(m) => m,
            MapImpl::Neural(m) => m,
        }
    }

    /// Trains a model on the result stores found under `runs` (see
    /// [`snapshots::find_stores`]); `log` receives progress lines.
    pub fn train(
        runs: &[PathBuf],
        options: &TrainOptions,
        log: &mut dyn FnMut(&str),
    ) -> Result<Model, RomError> {
        let start = Instant::now();
        let stores = snapshots::find_stores(runs)?;
        let snaps = snapshots::load(&stores)?;
        log(&format!(
            "{} runs, {} snapshots of {} particles ({}D)",
            snaps.runs.len(),
            snaps.count(),
            snaps.particles(),
            snaps.dimension
        ));
        let scene = &snaps.scene;
        let cell_size = scene
            .pointer("/domain/cell_size")
            .and_then(|v| v.as_f64())
            .ok_or_else(|| {
                RomError::Training(format!(
                    "{}: the stored scene has no domain.cell_size",
                    stores[0].display()
                ))
            })?;
        let pod = crate::pod::pod(&snaps, options.latent)?;
        log(&format!(
            "POD: {} modes capture {:.6} of the squared displacement",
            pod.count, pod.captured
        ));
        let dim = snaps.dimension;
        let (map, initial_latent, fit_error, mode_grid, network) = match options.kind {
            ModelKind::Linear => {
                let spacing = options.mode_spacing.unwrap_or(0.5 * cell_size);
                let (map, report) =
                    LinearMap::fit(dim, &snaps.reference, &pod.modes, pod.count, spacing)?;
                log(&format!(
                    "mode fields: {} nodes at {spacing} m, misfit {:.2e} (relative RMS) after {} \
                     iterations",
                    map.grid.len(),
                    report.relative_rms,
                    report.iterations
                ));
                let fit = fit_error(&map, &snaps, &pod.coefficients, options.latent)?;
                let grid = map.grid.clone();
                (
                    MapImpl::Linear(map),
                    vec![0.0; options.latent],
                    fit,
                    Some(grid),
                    None,
                )
            }
            ModelKind::Neural => {
                let mut report = |epoch: usize, mse: f64| {
                    if epoch.is_multiple_of(25) {
                        log(&format!(
                            "epoch {epoch}: RMS position misfit {:.3e} m",
                            mse.sqrt()
                        ));
                    }
                };
                let (map, latents) = NeuralMap::train(
                    dim,
                    &snaps.reference,
                    &snaps.positions,
                    options.latent,
                    &pod.coefficients,
                    &options.neural,
                    &mut report,
                )?;
                // The undeformed state: the mean code of the runs' first frames.
                let mut initial = vec![0.0; options.latent];
                let mut first = 0;
                for run in &snaps.runs {
                    for (i, v) in initial.iter_mut().enumerate() {
                        *v += latents[first * options.latent + i] / snaps.runs.len() as f64;
                    }
                    first += run.times.len();
                }
                let fit = fit_error(&map, &snaps, &latents, options.latent)?;
                let (description, _) = map.to_arrays();
                (MapImpl::Neural(map), initial, fit, None, Some(description))
            }
        };
        log(&format!(
            "training fit: RMS position misfit {:.3e} of the RMS displacement",
            fit_error
        ));
        let info = ModelInfo {
            format: FORMAT,
            kind: options.kind,
            dimension: dim,
            latent: options.latent,
            initial_latent,
            training: TrainingInfo {
                runs: stores.iter().map(|p| p.display().to_string()).collect(),
                snapshots: snaps.count(),
                particles: snaps.particles(),
                pod_captured: pod.captured,
                singular_values: pod.singular_values.iter().take(32).copied().collect(),
                fit_error,
                seconds: start.elapsed().as_secs_f64(),
                scene: scene
                    .get("name")
                    .and_then(|v| v.as_str())
                    .unwrap_or("")
                    .to_string(),
                kernel: scene
                    .pointer("/solver/kernel")
                    .cloned()
                    .unwrap_or(serde_json::Value::Null),
                cell_size,
                reference_box: bounding_box(&snaps.reference, dim),
            },
            mode_grid,
            network,
        };
        Ok(Model { info, map })
    }

    /// Writes the model to `path` (safetensors).
    pub fn save(&self, path: &Path) -> Result<(), RomError> {
        let arrays = match &self.map {
            MapImpl::Linear(m) => {
                let g = &m.grid;
                let mut shape: Vec<usize> = g.nodes[..g.dimension].to_vec();
                shape.push(m.latent);
                shape.push(g.dimension);
                vec![NamedArray::new("modes", shape, m.coefficients.clone())]
            }
            MapImpl::Neural(m) => m.to_arrays().1,
        };
        let info = serde_json::to_value(&self.info).map_err(|e| RomError::File {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        file::save(path, &info, &arrays)
    }

    /// Reads a model written by [`Model::save`].
    pub fn load(path: &Path) -> Result<Model, RomError> {
        let (value, mut arrays) = file::load(path)?;
        let bad = |message: String| RomError::BadModel {
            path: path.display().to_string(),
            message,
        };
        let info: ModelInfo = serde_json::from_value(value)
            .map_err(|e| bad(format!("the description is not a model description: {e}")))?;
        if info.format != FORMAT {
            return Err(bad(format!(
                "format {} is not the supported {FORMAT}",
                info.format
            )));
        }
        if !(info.dimension == 2 || info.dimension == 3) || info.latent == 0 {
            return Err(bad(format!(
                "dimension {} and latent {} are not a valid model",
                info.dimension, info.latent
            )));
        }
        if info.initial_latent.len() != info.latent {
            return Err(bad(format!(
                "initial_latent has {} values for {} coordinates",
                info.initial_latent.len(),
                info.latent
            )));
        }
        let map = match info.kind {
            ModelKind::Linear => {
                let grid = info
                    .mode_grid
                    .clone()
                    .ok_or_else(|| bad("a linear model without mode_grid".into()))?;
                if grid.dimension != info.dimension
                    || grid.origin.len() != grid.dimension
                    || grid.spacing.is_nan()
                    || grid.spacing <= 0.0
                    || grid.nodes[..grid.dimension].iter().any(|&n| n < 3)
                {
                    return Err(bad(format!("mode_grid {grid:?} is not valid")));
                }
                let mut shape: Vec<usize> = grid.nodes[..grid.dimension].to_vec();
                shape.push(info.latent);
                shape.push(grid.dimension);
                let coefficients = file::take(path, &mut arrays, "modes", &shape)?;
                if coefficients.iter().any(|v| !v.is_finite()) {
                    return Err(bad("array `modes` holds non-finite values".into()));
                }
                MapImpl::Linear(LinearMap {
                    grid,
                    latent: info.latent,
                    coefficients,
                })
            }
            ModelKind::Neural => {
                let description = info
                    .network
                    .clone()
                    .ok_or_else(|| bad("a neural model without network description".into()))?;
                let map = NeuralMap::from_arrays(path, &description, arrays)?;
                if map.dimension() != info.dimension || map.latent() != info.latent {
                    return Err(bad(
                        "the network's dimension or latent size differs from the model's".into(),
                    ));
                }
                MapImpl::Neural(map)
            }
        };
        Ok(Model { info, map })
    }

    /// Checks that `scene` is one this model can run: same dimension, kernel and cell size
    /// as the training scene, elastic materials only (no per-particle history, which the map
    /// cannot carry), dynamic mechanics without extra physics.
    pub fn check_scene(&self, scene: &ValidatedScene) -> Result<(), RomError> {
        let s = &scene.scene;
        let mismatch = |path: &str, message: String| RomError::Mismatch {
            path: path.to_string(),
            message,
        };
        if s.dimension as usize != self.info.dimension {
            return Err(mismatch(
                "dimension",
                format!(
                    "the scene is {}D but the model was trained on {}D runs",
                    s.dimension, self.info.dimension
                ),
            ));
        }
        let kernel = serde_json::to_value(s.solver.kernel).unwrap_or(serde_json::Value::Null);
        if kernel != self.info.training.kernel {
            return Err(mismatch(
                "solver.kernel",
                format!(
                    "the scene uses kernel {kernel} but the model was trained with {}",
                    self.info.training.kernel
                ),
            ));
        }
        if !s.loads.is_empty() {
            return Err(mismatch(
                "loads",
                "a reduced run carries gravity and obstacles, not loads: remove them".into(),
            ));
        }
        if s.solver.kernel == mpm_core::scene::KernelName::Cpdi2 {
            return Err(mismatch(
                "solver.kernel",
                "a reduced run interpolates at particle centres, not through CPDI's domains".into(),
            ));
        }
        let h = self.info.training.cell_size;
        if (s.domain.cell_size - h).abs() > 1e-9 * h {
            return Err(mismatch(
                "domain.cell_size",
                format!(
                    "the scene's grid has cells of {} m but the model was trained at {h} m; a \
                     reduced run uses the training grid (particles may be finer)",
                    s.domain.cell_size
                ),
            ));
        }
        let [lo, hi] = &self.info.training.reference_box;
        for body in &scene.bodies {
            let dim = self.info.dimension;
            for (p, x) in body.positions.chunks_exact(dim).enumerate() {
                if (0..dim).any(|d| x[d] < lo[d] - 0.5 * h || x[d] > hi[d] + 0.5 * h) {
                    return Err(mismatch(
                        &format!("bodies[{}]", body.body),
                        format!(
                            "particle {p} at {x:?} lies outside the region the model was trained \
                             on ({lo:?} to {hi:?}, half a cell of slack)"
                        ),
                    ));
                }
            }
        }
        if !s.physics.is_empty() {
            return Err(mismatch(
                "physics",
                "reduced runs cover mechanics only; remove the physics sections".into(),
            ));
        }
        if s.solver.mechanics != Mechanics::Dynamic {
            return Err(mismatch(
                "solver.mechanics",
                "reduced runs need dynamic mechanics".into(),
            ));
        }
        if !matches!(s.solver.transfer, Transfer::Apic | Transfer::Pic) {
            return Err(mismatch(
                "solver.transfer",
                "reduced runs support the apic and pic transfers".into(),
            ));
        }
        if s.solver.anti_locking != AntiLocking::None {
            return Err(mismatch(
                "solver.anti_locking",
                "reduced runs take F from the map; anti-locking does not apply".into(),
            ));
        }
        for (name, material) in &scene.materials {
            let path = format!("materials.{name}");
            if !material.state_fields().is_empty() {
                let fields: Vec<&str> = material.state_fields().iter().map(|f| f.name).collect();
                return Err(mismatch(
                    &path,
                    format!(
                        "this material keeps per-particle history ({}), which the reduced map \
                         cannot carry; reduced runs need elastic materials",
                        fields.join(", ")
                    ),
                ));
            }
            if material.needs_velocity_gradient() || !material.shared_reads().is_empty() {
                return Err(mismatch(
                    &path,
                    "this material is rate- or field-dependent; reduced runs need elastic \
                     materials"
                        .into(),
                ));
            }
        }
        Ok(())
    }
}

/// Lower and upper corners of `points` (`dim` numbers each).
fn bounding_box(points: &[f64], dim: usize) -> [Vec<f64>; 2] {
    let mut lo = vec![f64::INFINITY; dim];
    let mut hi = vec![f64::NEG_INFINITY; dim];
    for x in points.chunks_exact(dim) {
        for d in 0..dim {
            lo[d] = lo[d].min(x[d]);
            hi[d] = hi[d].max(x[d]);
        }
    }
    [lo, hi]
}

/// RMS misfit of `map` at the training snapshots with codes `codes` (`[snapshot][latent]`),
/// relative to the RMS displacement.
fn fit_error(
    map: &dyn ReducedMap,
    snaps: &Snapshots,
    codes: &[f64],
    latent: usize,
) -> Result<f64, RomError> {
    let n = snaps.particles();
    let dim = snaps.dimension;
    // Every 4th snapshot at most 20000 particles: enough for a figure, cheap for the net.
    let stride = n.div_ceil(20_000).max(1);
    let which: Vec<u32> = (0..n).step_by(stride).map(|p| p as u32).collect();
    let points: Vec<f64> = which
        .iter()
        .flat_map(|&p| snaps.reference[p as usize * dim..(p as usize + 1) * dim].to_vec())
        .collect();
    let mut bound = map.bind(&points)?;
    let local: Vec<u32> = (0..which.len() as u32).collect();
    let mut x = vec![0.0; which.len() * dim];
    let (mut err2, mut disp2) = (0.0, 0.0);
    for s in 0..snaps.count() {
        bound.positions(&codes[s * latent..(s + 1) * latent], &local, &mut x)?;
        for (k, &p) in which.iter().enumerate() {
            for d in 0..dim {
                let truth = snaps.positions[(s * n + p as usize) * dim + d];
                let e = x[k * dim + d] - truth;
                let u = truth - snaps.reference[p as usize * dim + d];
                err2 += e * e;
                disp2 += u * u;
            }
        }
    }
    Ok((err2 / disp2.max(1e-300)).sqrt())
}
