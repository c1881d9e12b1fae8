//! The `output` section (frames and fields) and the `stop` section (bounds that stop a
//! run going wrong); their types and checks.

use super::validator::Validator;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Largest stress averaging radius, in cells.
const MAX_AVERAGING_CELLS: f64 = 20.0;

/// Output schedule and fields.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Number of frames after the initial one, evenly spaced over `end_time`.
    #[serde(default = "default_frames")]
    pub frames: u32,
    /// Particle fields to store: `x`, `v`, `stress`, `F`, `J`, `mass`, `volume`, `material`,
    /// in 2D `stress_zz` (σzz, the stress across the plane in plane strain), plus any field
    /// a material or physics declares.
    #[serde(default = "default_fields")]
    pub fields: Vec<String>,
    /// Checkpoints of the whole state, so `mpm run --resume STORE` can continue the run
    /// (only the last one is kept in the store).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint: Option<CheckpointSchedule>,
    /// In a staged scene, keep the state each stage with it ends with in the store
    /// (`stages/<index>-<name>/end_state`), so `mpm run SCENE --from STORE --stage NEXT`
    /// can start at the next stage; a stage with `checkpoint` keeps it anyway. Unlike a
    /// checkpoint it is allowed where a physics keeps state outside the particles (the
    /// gap-averaged fill): a stage hands over only what stages hand over.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub end_state: bool,
    /// Radius, m, of the stress average each stage's summary reports besides the peak
    /// (`averaged_von_mises`): the largest von Mises stress averaged over the particles of
    /// one material within this distance of a particle. Unlike the peak it converges under
    /// refinement at a singular corner.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stress_averaging_radius: Option<f64>,
    /// Darveaux's interface layer: each stage also reports the inelastic work of every
    /// material that keeps it (a solder joint) averaged over its particles within
    /// `thickness` of each material in `along` (the pads a joint's crack runs along), and
    /// the cycles to crack at the layer with the most work. The whole joint's average
    /// spreads the work of its corners over its bulk and gives longer lives.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fatigue_layer: Option<FatigueLayer>,
}

/// The layer of a joint next to the bodies its crack runs along (`output.fatigue_layer`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FatigueLayer {
    /// Thickness of the layer, m: a joint's particle within this distance of a particle
    /// of a material in `along` is in that material's layer (Darveaux: 25 µm for a
    /// 0.5 mm ball; a tenth of the joint's height or so).
    pub thickness: f64,
    /// The materials whose interface with the joint carries a layer (die, substrate, pad).
    pub along: Vec<String>,
}

/// When a run writes a checkpoint: every `steps` steps, or every `time` seconds of
/// simulated time (at the end of the first step that reaches it), or both.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CheckpointSchedule {
    /// Steps between checkpoints.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps: Option<u64>,
    /// Simulated time between checkpoints, seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
}

fn default_frames() -> u32 {
    20
}
fn default_fields() -> Vec<String> {
    vec!["x".into(), "v".into()]
}

impl Default for Output {
    fn default() -> Self {
        Self {
            frames: default_frames(),
            fields: default_fields(),
            checkpoint: None,
            end_state: false,
            stress_averaging_radius: None,
            fatigue_layer: None,
        }
    }
}

/// Bounds that stop a run going wrong; NaN/inf and det F <= 0 always stop it.
#[derive(Clone, Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StopCriteria {
    /// Largest particle speed allowed, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_speed: Option<f64>,
    /// Largest allowed growth of the total energy, as a fraction of the largest mechanical
    /// energy (kinetic + strain) seen so far.
    #[serde(default = "default_energy_growth")]
    pub max_energy_growth: f64,
    /// Smallest time step allowed before the run stops, seconds.
    #[serde(default = "default_min_dt")]
    pub min_dt: f64,
}

fn default_energy_growth() -> f64 {
    0.5
}
fn default_min_dt() -> f64 {
    1e-14
}

impl Default for StopCriteria {
    fn default() -> Self {
        Self {
            max_speed: None,
            max_energy_growth: default_energy_growth(),
            min_dt: default_min_dt(),
        }
    }
}

impl Output {
    /// Checks the output schedule (`cell_size` bounds the stress averaging radius and the
    /// fatigue layer; the layer's materials must be among `materials`).
    pub(super) fn validate<'a>(
        &self,
        v: &mut Validator,
        cell_size: f64,
        materials: impl Iterator<Item = &'a String> + Clone,
    ) {
        if self.frames == 0 {
            v.err("output.frames", "must be at least 1");
        }
        if let Some(c) = &self.checkpoint {
            match (c.steps, c.time) {
                (None, None) => v.err(
                    "output.checkpoint",
                    "give `steps` (steps between checkpoints) or `time` (seconds between them)",
                ),
                (Some(0), _) => v.err("output.checkpoint.steps", "must be at least 1"),
                _ => {}
            }
            if let Some(t) = c.time {
                v.positive("output.checkpoint.time", t);
            }
        }
        if let Some(r) = self.stress_averaging_radius {
            v.positive("output.stress_averaging_radius", r);
            if r > MAX_AVERAGING_CELLS * cell_size {
                v.err(
                    "output.stress_averaging_radius",
                    format!(
                        "must be at most {MAX_AVERAGING_CELLS} cells (domain.cell_size {cell_size} m; got {r} m): the average's cost grows with its area"
                    ),
                );
            }
        }
        if let Some(layer) = &self.fatigue_layer {
            layer.validate(v, cell_size, materials);
        }
    }
}

impl FatigueLayer {
    /// Checks the thickness (positive, at most [`MAX_AVERAGING_CELLS`] cells) and that
    /// `along` names materials of the scene.
    fn validate<'a>(
        &self,
        v: &mut Validator,
        cell_size: f64,
        materials: impl Iterator<Item = &'a String> + Clone,
    ) {
        let path = "output.fatigue_layer";
        v.positive(&format!("{path}.thickness"), self.thickness);
        if self.thickness > MAX_AVERAGING_CELLS * cell_size {
            v.err(
                format!("{path}.thickness"),
                format!(
                    "must be at most {MAX_AVERAGING_CELLS} cells (domain.cell_size {cell_size} m; got {} m): the layer is a thin slice of the joint",
                    self.thickness
                ),
            );
        }
        if self.along.is_empty() {
            v.err(
                format!("{path}.along"),
                "name at least one material whose interface with the joint carries a layer",
            );
        }
        for (i, name) in self.along.iter().enumerate() {
            if !materials.clone().any(|m| m == name) {
                let known: Vec<&str> = materials.clone().map(String::as_str).collect();
                v.err(
                    format!("{path}.along[{i}]"),
                    format!(
                        "no material named `{name}` (scene has: {})",
                        known.join(", ")
                    ),
                );
            }
        }
    }
}

impl StopCriteria {
    /// Checks the stop bounds.
    pub(super) fn validate(&self, v: &mut Validator) {
        if let Some(m) = self.max_speed {
            v.positive("stop.max_speed", m);
        }
        v.positive("stop.max_energy_growth", self.max_energy_growth);
        if !(self.min_dt.is_finite() && self.min_dt >= 0.0) {
            v.err("stop.min_dt", "must be a finite number >= 0");
        }
    }
}
