//! Watches each step for the first particle of a material to fail (damage 1), so a run
//! (each stage of a staged run) reports when and where its first crack started, to the
//! step, not only to the frame. Particles that had failed when the run (stage) began are
//! known by their output index and do not count. A material stops being watched once it
//! has its onset, so the watch costs one pass over the damage of the materials still
//! whole per step, and nothing in scenes without damage.

use crate::checkpoint::Checkpoint;
use crate::damage_measures::{FailureOnset, damage_field};
use crate::particles::Particles;
use std::collections::BTreeMap;

/// One material group being watched.
struct Watched {
    /// Index of the group in `Particles::groups`.
    group: usize,
    /// Its `damage` state field.
    field: usize,
    /// Output indices of its particles failed when the watch began, sorted.
    failed_before: Vec<u32>,
}

/// The first failure per material since the run (stage) began.
pub(super) struct FailureWatch {
    watched: Vec<Watched>,
    onsets: BTreeMap<String, FailureOnset>,
}

impl FailureWatch {
    /// Starts watching every group whose law keeps damage; what has failed now is old.
    pub(super) fn start<const D: usize>(particles: &Particles<D>) -> Self {
        let watched = particles
            .groups
            .iter()
            .enumerate()
            .filter_map(|(g, group)| {
                let field = damage_field(group)?;
                let mut failed_before: Vec<u32> = group.state[field]
                    .iter()
                    .enumerate()
                    .filter(|(_, d)| **d >= 1.0)
                    .map(|(k, _)| particles.id[group.range.start + k])
                    .collect();
                failed_before.sort_unstable();
                Some(Watched {
                    group: g,
                    field,
                    failed_before,
                })
            })
            .collect();
        Self {
            watched,
            onsets: BTreeMap::new(),
        }
    }

    /// The watch a checkpoint written by [`FailureWatch::save`] held; a checkpoint without
    /// one (written before the watch existed) starts the watch afresh.
    pub(super) fn load<const D: usize>(particles: &Particles<D>, c: &Checkpoint) -> Self {
        let mut watch = Self::start(particles);
        let saved = c.state("failure_watch");
        if saved.is_null() {
            return watch;
        }
        for w in &mut watch.watched {
            let before = &saved["failed_before"][w.group.to_string()];
            w.failed_before = serde_json::from_value(before.clone()).unwrap_or_default();
        }
        watch.onsets = serde_json::from_value(saved["onsets"].clone()).unwrap_or_default();
        watch
            .watched
            .retain(|w| !watch.onsets.contains_key(&particles.groups[w.group].name));
        watch
    }

    /// Puts the watch in a checkpoint, so a resumed run reports the same onsets.
    pub(super) fn save(&self, c: &mut Checkpoint) {
        let before: serde_json::Map<String, serde_json::Value> = self
            .watched
            .iter()
            .map(|w| (w.group.to_string(), serde_json::json!(w.failed_before)))
            .collect();
        c.set_state(
            "failure_watch",
            serde_json::json!({"failed_before": before, "onsets": self.onsets}),
        );
    }

    /// Looks for newly failed particles after a step that ended at `time`.
    pub(super) fn observe<const D: usize>(&mut self, particles: &Particles<D>, time: f64) {
        if self.watched.is_empty() {
            return;
        }
        let mut found = false;
        for w in &self.watched {
            let group = &particles.groups[w.group];
            if self.onsets.contains_key(&group.name) {
                continue;
            }
            let new = group.state[w.field]
                .iter()
                .enumerate()
                .filter(|(_, d)| **d >= 1.0)
                .map(|(k, _)| group.range.start + k)
                .filter(|&p| w.failed_before.binary_search(&particles.id[p]).is_err())
                .min_by_key(|&p| particles.id[p]);
            if let Some(p) = new {
                let mut position = [0.0; 3];
                for (a, v) in particles.position[p].iter().enumerate() {
                    position[a] = *v;
                }
                self.onsets.insert(
                    group.name.clone(),
                    FailureOnset {
                        time,
                        position,
                        particle: particles.id[p],
                    },
                );
                found = true;
            }
        }
        if found {
            let onsets = &self.onsets;
            self.watched
                .retain(|w| !onsets.contains_key(&particles.groups[w.group].name));
        }
    }

    /// The onsets found so far, by material.
    pub(super) fn onsets(&self) -> &BTreeMap<String, FailureOnset> {
        &self.onsets
    }
}
