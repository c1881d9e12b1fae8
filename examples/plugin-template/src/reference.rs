//! A reference a plugin brings for its own physics: the decay rate of the Kelvin–Voigt
//! bar's first mode, β = η k² / ρ with k = π / 2L, against the run's kinetic energy.
//!
//! Copy this file to verify your own law: a parameter struct (the scene's `reference`
//! section), a [`ReferenceLaw`] that looks at every output frame, and a factory returned
//! from `Plugin::references`.

use mpm_core::output::Comparison;
use mpm_core::reference::{
    Frame, Reference, ReferenceFactory, ReferenceLaw, TypedReferenceFactory, compare,
};
use mpm_core::scene::{Issue, Scene};
use mpm_core::section::Checks;
use schemars::JsonSchema;
use serde::Deserialize;
use std::sync::Arc;

/// The first mode of a fixed–free Kelvin–Voigt bar (ν = 0) decays as exp(−β t), β = η k²/ρ,
/// k = π/2L. The run starts in that mode with all its energy kinetic; its last frame must
/// fall on a whole number of periods, where the energy is kinetic again. Error: relative
/// error of the decay rate measured from the kinetic energy at the first and last frames.
#[derive(Clone, Copy, Debug, Deserialize, JsonSchema, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct KelvinVoigtDecayParams {
    /// Length of the bar, m.
    pub length: f64,
    /// Density of the material, kg/m³.
    pub density: f64,
    /// Viscosity of the dashpot, Pa s.
    pub viscosity: f64,
}

/// The kinetic energy at the first frame and the decay rate measured at the last.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct KelvinVoigtDecay {
    expected: f64,
    initial_energy: Option<f64>,
    measured: Option<f64>,
}

impl ReferenceLaw for KelvinVoigtDecay {
    fn kind(&self) -> &'static str {
        "relative error of the first mode's decay rate (Kelvin-Voigt bar, kinetic energy at the first and last frames)"
    }

    fn observe<const D: usize>(&mut self, frame: Frame<'_, D>) {
        let p = frame.particles;
        let kinetic: f64 = (0..p.len())
            .map(|i| 0.5 * p.mass[i] * p.velocity[i].norm_squared())
            .sum();
        match self.initial_energy {
            None => self.initial_energy = Some(kinetic),
            Some(initial) if frame.last && frame.time > 0.0 => {
                // E(t) = E(0) exp(−2 β t).
                self.measured = Some(-(kinetic / initial).ln() / (2.0 * frame.time));
            }
            Some(_) => {}
        }
    }

    fn error(&self) -> Option<f64> {
        Some((self.measured? - self.expected).abs() / self.expected)
    }

    fn expected(&self) -> Option<f64> {
        Some(self.expected)
    }

    fn measured(&self) -> Option<f64> {
        self.measured
    }

    fn comparisons(&self) -> Vec<Comparison> {
        self.measured
            .map(|m| vec![compare("decay_rate", m, self.expected)])
            .unwrap_or_default()
    }
}

fn build(
    p: KelvinVoigtDecayParams,
    path: &str,
    _scene: &Scene,
) -> Result<Arc<dyn Reference>, Vec<Issue>> {
    let mut c = Checks::new(path);
    c.positive("length", p.length);
    c.positive("density", p.density);
    c.positive("viscosity", p.viscosity);
    c.finish()?;
    let k = std::f64::consts::PI / (2.0 * p.length);
    Ok(Arc::new(KelvinVoigtDecay {
        expected: p.viscosity * k * k / p.density,
        initial_energy: None,
        measured: None,
    }))
}

/// The `kelvin_voigt_decay` reference type.
pub fn factory() -> Box<dyn ReferenceFactory> {
    Box::new(TypedReferenceFactory::new("kelvin_voigt_decay", build))
}
