//! Fatigue figures of a staged run's stages, per material whose law accumulates its
//! inelastic work ([`crate::material::INELASTIC_WORK`], the `anand` solder law): the work
//! density averaged over the material's reference volume at the stage's end, its increase
//! over the stage, and, when the law has a fatigue law and the stage is one thermal
//! cycle, the cycles to crack initiation that increase gives (energy-based solder fatigue
//! in the manner of Darveaux and Syed, who average the work over the joint's volume).
//! With `output.fatigue_layer` the same figures for the joint's layers next to the named
//! materials (Darveaux's interface layer, where the crack runs).

use crate::cell_hash::CellHash;
use crate::material::INELASTIC_WORK;
use crate::particles::Particles;
use crate::scene::FatigueLayer;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Inelastic work over a stage, averaged over a volume (a material's, or a layer of it),
/// and the lives its fatigue law gives at the stage's work per cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct WorkFigures {
    /// Inelastic work density accumulated since the run began, averaged over the
    /// reference volume, J/m³.
    pub work: f64,
    /// Its increase over this stage, J/m³: the work per cycle when the stage is a cycle.
    pub work_in_stage: f64,
    /// Cycles to crack initiation at `work_in_stage` per cycle, from the law's fatigue law
    /// (`None` without one, or without work in the stage).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cycles_to_crack: Option<f64>,
    /// Cycles to failure (initiation, then the crack across the joint) at `work_in_stage`
    /// per cycle, when the fatigue law grows the crack (`None` otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cycles_to_failure: Option<f64>,
}

impl WorkFigures {
    /// The figures of an average `work` that was `start` when the stage began.
    fn of(work: f64, start: f64, material: &dyn crate::material::Material) -> Self {
        let in_stage = work - start;
        Self {
            work,
            work_in_stage: in_stage,
            cycles_to_crack: material.cycles_to_crack(in_stage),
            cycles_to_failure: material.cycles_to_failure(in_stage),
        }
    }
}

/// One material's inelastic work over a stage.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FatigueFigures {
    /// Averaged over the material's reference volume.
    #[serde(flatten)]
    pub whole: WorkFigures,
    /// The same figures averaged over the material's layer next to each material of
    /// `output.fatigue_layer.along` that it touches (empty without the setting).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub layers: BTreeMap<String, LayerFigures>,
}

/// The inelastic work of a joint's layer next to one material, over a stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LayerFigures {
    /// Averaged over the layer's reference volume.
    #[serde(flatten)]
    pub figures: WorkFigures,
    /// The layer's reference volume, m³ (m² in 2D).
    pub volume: f64,
}

impl FatigueFigures {
    /// The layer with the most work in the stage, and its figures (none without layers).
    pub fn critical_layer(&self) -> Option<(&str, &LayerFigures)> {
        self.layers
            .iter()
            .max_by(|a, b| {
                a.1.figures
                    .work_in_stage
                    .total_cmp(&b.1.figures.work_in_stage)
            })
            .map(|(name, f)| (name.as_str(), f))
    }
}

/// The fatigue figures of every material whose law keeps [`INELASTIC_WORK`], from the
/// figures at the stage's start, `before` (none for a material or layer not in it), and,
/// with `layer`, of its layers.
pub fn fatigue_figures<const D: usize>(
    particles: &Particles<D>,
    before: &BTreeMap<String, FatigueFigures>,
    layer: Option<&FatigueLayer>,
) -> BTreeMap<String, FatigueFigures> {
    let mut out: BTreeMap<String, FatigueFigures> = BTreeMap::new();
    // Weighted work and volume per material, its layers', and its law.
    type Sums<'a> = (f64, f64, BTreeMap<&'a str, (f64, f64)>);
    let mut sums: BTreeMap<&str, (Sums, &dyn crate::material::Material)> = BTreeMap::new();
    for group in &particles.groups {
        let Some(field) = group
            .material
            .state_fields()
            .iter()
            .position(|f| f.name == INELASTIC_WORK && f.components == 1)
        else {
            continue;
        };
        let entry = sums
            .entry(group.name.as_str())
            .or_insert(((0.0, 0.0, BTreeMap::new()), group.material.as_ref()));
        let work = &group.state[field];
        for (k, &w) in work.iter().enumerate() {
            let v0 = particles.volume0[group.range.start + k].abs();
            entry.0.0 += w * v0;
            entry.0.1 += v0;
        }
        for along in layer.iter().flat_map(|l| l.along.iter()) {
            let members = layer_members(particles, group.range.clone(), along, layer);
            let slot = entry.0.2.entry(along.as_str()).or_insert((0.0, 0.0));
            for p in members {
                let v0 = particles.volume0[p].abs();
                slot.0 += work[p - group.range.start] * v0;
                slot.1 += v0;
            }
        }
    }
    let mean = |weighted: f64, volume: f64| if volume > 0.0 { weighted / volume } else { 0.0 };
    for (name, ((weighted, volume, layers), material)) in sums {
        let previous = before.get(name);
        let layers = layers
            .into_iter()
            .filter(|(_, (_, v))| *v > 0.0)
            .map(|(along, (w, v))| {
                let start = previous
                    .and_then(|f| f.layers.get(along))
                    .map_or(0.0, |l| l.figures.work);
                let figures = LayerFigures {
                    figures: WorkFigures::of(mean(w, v), start, material),
                    volume: v,
                };
                (along.to_string(), figures)
            })
            .collect();
        let start = previous.map_or(0.0, |f| f.whole.work);
        let figures = FatigueFigures {
            whole: WorkFigures::of(mean(weighted, volume), start, material),
            layers,
        };
        out.insert(name.to_string(), figures);
    }
    out
}

/// The particles of `range` (one group of the joint's material) within the layer's
/// thickness of a particle of material `along`, in order. Allocates a cell hash of the
/// `along` particles; called once per stage end.
fn layer_members<const D: usize>(
    particles: &Particles<D>,
    range: std::ops::Range<usize>,
    along: &str,
    layer: Option<&FatigueLayer>,
) -> Vec<usize> {
    let Some(thickness) = layer.map(|l| l.thickness) else {
        return Vec::new();
    };
    let indices = particles
        .groups
        .iter()
        .filter(|g| g.name == along)
        .flat_map(|g| g.range.clone());
    let hash = CellHash::new(thickness, &particles.position, indices);
    if hash.is_empty() {
        return Vec::new();
    }
    range
        .filter(|&p| {
            let x = particles.position[p];
            hash.near(&x)
                .any(|q| (particles.position[q] - x).norm() <= thickness)
        })
        .collect()
}
