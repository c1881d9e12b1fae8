//! Removing particles at a hand-over between stages (`stages[i].remove`): the gap's
//! particles a fill left empty leave the run, so the cure stage starts with the underfill
//! where the liquid is and empty space (the voids) where it is not.
//!
//! Particles are named by their index over the scene's bodies in body order (the id a run
//! without removals gives them); a run keeps the sorted list of those it removed and
//! numbers the rest 0, 1, ... in that order, as a scene with those particles left out of
//! its bodies would. The next stage is built from exactly such a scene
//! ([`without_particles`]) and takes over a checkpoint whose particle rows were taken out
//! the same way ([`remove_rows`]), so nothing downstream knows particles were removed.

use super::RunError;
use crate::checkpoint::Checkpoint;
use crate::scene::{RemoveParticles, ValidatedScene};

/// The original index of each particle the run still has, in id order.
pub(super) fn kept(total: usize, removed: &[u32]) -> Vec<u32> {
    let mut out = Vec::with_capacity(total - removed.len().min(total));
    let mut next = removed.iter().peekable();
    for id in 0..total as u32 {
        if next.peek() == Some(&&id) {
            next.next();
        } else {
            out.push(id);
        }
    }
    out
}

/// The material of every original particle.
pub(super) fn materials_by_particle(full: &ValidatedScene) -> Vec<&str> {
    full.bodies
        .iter()
        .flat_map(|b| {
            let name = full.scene.bodies[b.body].material.as_str();
            std::iter::repeat_n(name, b.volumes.len())
        })
        .collect()
}

/// The names of the material groups of a run of `scene`: one per material a body is made
/// of, in sorted order (the order of their contiguous rows).
pub(super) fn group_names(scene: &ValidatedScene) -> Vec<&str> {
    let mut names: Vec<&str> = scene
        .bodies
        .iter()
        .map(|b| scene.scene.bodies[b.body].material.as_str())
        .collect();
    names.sort_unstable();
    names.dedup();
    names
}

/// The rows of a hand-over state that had some particles removed already.
pub(super) struct StateRows<'a> {
    /// The material of every original particle.
    pub materials: Vec<&'a str>,
    /// The original index of each particle of the state, by id.
    pub kept: Vec<u32>,
    /// The state's particle id of each row.
    pub ids: &'a [f64],
}

/// The rows of the state `c`, which had `removed` removed.
pub(super) fn state_rows<'a>(
    c: &'a Checkpoint,
    full: &'a ValidatedScene,
    removed: &[u32],
    path: &str,
) -> Result<StateRows<'a>, RunError> {
    let materials = materials_by_particle(full);
    let kept = kept(materials.len(), removed);
    let ids = c
        .get("particles.id", kept.len())
        .map_err(|e| refused(path, format!("the hand-over state: {e}")))?;
    Ok(StateRows {
        materials,
        kept,
        ids,
    })
}

pub(super) fn refused(path: &str, message: String) -> RunError {
    RunError::Refused {
        path: path.into(),
        message,
    }
}

/// The particles `rule` removes from the state `c` the stage before left (it had removed
/// `removed` already), added to `removed`; sorted original indices.
pub(super) fn apply_rule(
    c: &Checkpoint,
    rule: &RemoveParticles,
    removed: &[u32],
    full: &ValidatedScene,
    path: &str,
) -> Result<Vec<u32>, RunError> {
    let StateRows {
        materials,
        kept,
        ids,
    } = state_rows(c, full, removed, path)?;
    let n = kept.len();
    let values = c
        .arrays
        .get(&format!("shared.{}", rule.field))
        .filter(|v| v.len() == n)
        .ok_or_else(|| {
            refused(
                &format!("{path}.field"),
                format!(
                    "the stage before left no particle field `{}` to judge by",
                    rule.field
                ),
            )
        })?;
    let mut out = removed.to_vec();
    for (&id, &value) in ids.iter().zip(values) {
        let original = kept[id as usize];
        let applies = rule.materials.is_empty()
            || rule
                .materials
                .iter()
                .any(|m| m == materials[original as usize]);
        if applies && value < rule.below {
            out.push(original);
        }
    }
    out.sort_unstable();
    out.dedup();
    if out.len() == materials.len() {
        return Err(refused(
            path,
            format!(
                "every particle has `{}` below {}: nothing would be left to run",
                rule.field, rule.below
            ),
        ));
    }
    Ok(out)
}

/// `scene` with the particles `removed` (sorted original indices) left out of its bodies.
pub(super) fn without_particles(scene: &ValidatedScene, removed: &[u32]) -> ValidatedScene {
    let mut next = removed.iter().peekable();
    let mut original = 0u32;
    let dim = scene.scene.dimension as usize;
    let bodies = scene
        .bodies
        .iter()
        .map(|b| {
            let mut out = crate::scene::BodyParticles {
                body: b.body,
                spacing: b.spacing,
                ..Default::default()
            };
            for p in 0..b.volumes.len() {
                if next.peek() == Some(&&original) {
                    next.next();
                } else {
                    out.positions
                        .extend_from_slice(&b.positions[p * dim..(p + 1) * dim]);
                    out.velocities
                        .extend_from_slice(&b.velocities[p * dim..(p + 1) * dim]);
                    out.volumes.push(b.volumes[p]);
                }
                original += 1;
            }
            out
        })
        .collect();
    ValidatedScene {
        scene: scene.scene.clone(),
        json: scene.json.clone(),
        materials: scene.materials.clone(),
        bodies,
        physics: scene.physics.clone(),
        reference: scene.reference.clone(),
        stages: Vec::new(),
    }
}

/// `c` (a state with the particles `before` removed) with the rows of the particles in
/// `after` but not in `before` taken out and the ids numbered anew: every per-particle
/// array (`particles.*`, `shared.*`, the stress update's applied free strain) and every
/// material group's state.
pub(super) fn remove_rows(
    c: &Checkpoint,
    full: &ValidatedScene,
    before: &[u32],
    after: &[u32],
) -> Result<Checkpoint, RunError> {
    let path = "stages";
    let StateRows {
        materials,
        kept: kept_before,
        ids,
    } = state_rows(c, full, before, path)?;
    let n = kept_before.len();
    let mut new_id = vec![u32::MAX; materials.len()];
    for (k, &original) in kept(materials.len(), after).iter().enumerate() {
        new_id[original as usize] = k as u32;
    }
    let originals: Vec<usize> = ids
        .iter()
        .map(|&i| kept_before[i as usize] as usize)
        .collect();
    let keep: Vec<bool> = originals.iter().map(|&o| new_id[o] != u32::MAX).collect();
    let group_names = group_names(full);
    let mut group_rows = Vec::with_capacity(group_names.len());
    let mut start = 0;
    for name in &group_names {
        let count = originals.iter().filter(|&&o| materials[o] == *name).count();
        group_rows.push(start..start + count);
        start += count;
    }
    let filter = |values: &[f64], rows: std::ops::Range<usize>, name: &str| {
        if values.is_empty() || rows.is_empty() {
            return Ok(Vec::new());
        }
        if !values.len().is_multiple_of(rows.len()) {
            return Err(refused(
                path,
                format!("the hand-over array `{name}` is not a whole number of rows"),
            ));
        }
        let width = values.len() / rows.len();
        Ok(values
            .chunks_exact(width)
            .zip(&keep[rows])
            .filter(|(_, k)| **k)
            .flat_map(|(row, _)| row.iter().copied())
            .collect())
    };
    let mut out = Checkpoint::default();
    for (name, values) in &c.arrays {
        let kept_values = if name == "particles.id" {
            originals
                .iter()
                .filter(|&&o| new_id[o] != u32::MAX)
                .map(|&o| new_id[o] as f64)
                .collect()
        } else if name.starts_with("particles.")
            || name.starts_with("shared.")
            || name == "stress.applied_free_strain"
        {
            filter(values, 0..n, name)?
        } else if let Some(rest) = name.strip_prefix("group.") {
            let g: usize = rest
                .split('.')
                .next()
                .and_then(|g| g.parse().ok())
                .filter(|&g| g < group_rows.len())
                .ok_or_else(|| refused(path, format!("the hand-over array `{name}`")))?;
            filter(values, group_rows[g].clone(), name)?
        } else {
            values.clone()
        };
        out.put(name.clone(), kept_values);
    }
    out.state = c.state.clone();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::kept;

    #[test]
    fn kept_lists_the_particles_not_removed_in_order() {
        assert_eq!(kept(6, &[1, 4]), vec![0, 2, 3, 5]);
        assert_eq!(kept(3, &[]), vec![0, 1, 2]);
        assert_eq!(kept(2, &[0, 1]), Vec::<u32>::new());
    }
}
