//! Converting particles to another material at a hand-over between stages
//! (`stages[i].convert`): the liquid at the end of a fill becomes the underfill that cures,
//! where it is, with its temperature and cure.
//!
//! The stage's scene names the new materials in its bodies, so the run it builds groups
//! the particles by their new materials. The state the stage before left is laid out by
//! the old ones: [`convert_rows`] moves every particle's row into its new group (rows of a
//! group in output order) and starts the converted ones as the new material's
//! particles start a run: F = I, zero stress, the law's initial state and the mass from its
//! density. Velocity, position, the affine matrix and every physics field carry over.

use super::RunError;
use super::hand_over::{StateRows, group_names, materials_by_particle, refused, state_rows};
use crate::checkpoint::Checkpoint;
use crate::scene::ValidatedScene;

/// The state key that tells the stage taking over that particles were converted: it
/// computes their stress (and the step's wave speeds) before its first step.
pub(super) const CONVERTED: &str = "converted";

/// `c` (the state the stage before left, laid out by the materials of `before`'s bodies,
/// with the particles `removed` left out) laid out by the materials of `after`'s bodies,
/// the particles whose material changed started afresh in their new one.
pub(super) fn convert_rows(
    c: &Checkpoint,
    before: &ValidatedScene,
    after: &ValidatedScene,
    removed: &[u32],
) -> Result<Checkpoint, RunError> {
    let path = "stages";
    let StateRows {
        materials: old_materials,
        kept,
        ids,
    } = state_rows(c, before, removed, path)?;
    let new_materials = materials_by_particle(after);
    if new_materials.len() != old_materials.len() {
        return Err(refused(
            path,
            "a conversion changed the number of particles".into(),
        ));
    }
    let n = kept.len();
    let dim = after.scene.dimension as usize;
    let originals: Vec<usize> = ids.iter().map(|&i| kept[i as usize] as usize).collect();
    // Old groups: each row's group and its offset in the group's state arrays.
    let old_groups = group_names(before);
    let mut old_group = vec![0usize; n];
    let mut old_offset = vec![0usize; n];
    let mut counts = vec![0usize; old_groups.len()];
    for (row, &o) in originals.iter().enumerate() {
        let g = old_groups
            .iter()
            .position(|&name| name == old_materials[o])
            .ok_or_else(|| refused(path, "a particle of no material group".into()))?;
        old_group[row] = g;
        old_offset[row] = counts[g];
        counts[g] += 1;
    }
    // New rows: group by group in the new sorted order, each group's rows in output
    // order, as a run of the stage's scene lays them out at its start (so the converted
    // run follows one made of the new materials from the start bit for bit).
    let new_groups = group_names(after);
    let mut order = Vec::with_capacity(n);
    let mut new_ranges = Vec::with_capacity(new_groups.len());
    for name in &new_groups {
        let start = order.len();
        order.extend((0..n).filter(|&row| new_materials[originals[row]] == *name));
        order[start..].sort_unstable_by_key(|&row| ids[row] as u64);
        new_ranges.push(start..order.len());
    }
    if order.len() != n {
        return Err(refused(path, "a particle of no material group".into()));
    }
    let converted: Vec<bool> = order
        .iter()
        .map(|&row| old_materials[originals[row]] != new_materials[originals[row]])
        .collect();
    let permute = |values: &[f64], name: &str| -> Result<Vec<f64>, RunError> {
        if values.is_empty() {
            return Ok(Vec::new());
        }
        if !values.len().is_multiple_of(n) {
            return Err(refused(
                path,
                format!("the hand-over array `{name}` is not a whole number of rows"),
            ));
        }
        let width = values.len() / n;
        Ok(order
            .iter()
            .flat_map(|&row| values[row * width..(row + 1) * width].iter().copied())
            .collect())
    };
    let mut out = Checkpoint::default();
    for (name, values) in &c.arrays {
        if name.starts_with("group.")
            || name == "stress.group_wave_speed"
            || name.starts_with("total_lagrangian.")
        {
            // Rebuilt below; a total Lagrangian stage takes the converted state as its
            // reference.
            continue;
        }
        let per_row = name.starts_with("particles.")
            || name.starts_with("shared.")
            || name == "stress.applied_free_strain";
        let values = if per_row {
            permute(values, name)?
        } else {
            values.clone()
        };
        out.put(name.clone(), values);
    }
    // The converted particles start as the new material's do.
    let volume0 = out
        .arrays
        .get("particles.volume0")
        .cloned()
        .ok_or_else(|| refused(path, "the hand-over state has no volumes".into()))?;
    let new_material_of = |k: usize| new_materials[originals[order[k]]];
    for name in [
        "particles.deformation_gradient",
        "particles.stress",
        "particles.stress_zz",
        "particles.mass",
    ] {
        let Some(values) = out.arrays.get_mut(name) else {
            continue;
        };
        let width = values.len() / n.max(1);
        for k in (0..n).filter(|&k| converted[k]) {
            let row = &mut values[k * width..(k + 1) * width];
            match name {
                "particles.deformation_gradient" => {
                    row.fill(0.0);
                    for d in 0..dim {
                        row[d * dim + d] = 1.0;
                    }
                }
                "particles.mass" => {
                    row[0] = volume0[k] * after.materials[new_material_of(k)].density()
                }
                _ => row.fill(0.0),
            }
        }
    }
    // Material groups: the state of the particles that stayed, the initial state of those
    // that arrived.
    for (g, (name, range)) in new_groups.iter().zip(&new_ranges).enumerate() {
        let old = old_groups.iter().position(|o| o == name);
        let specs = after.materials[*name].state_fields();
        for (j, spec) in specs.iter().enumerate() {
            let width = spec.components;
            let fresh = spec.initial_values(1, dim);
            let source = old
                .map(|og| {
                    let key = format!("group.{og}.state.{j}");
                    c.get(&key, counts[og] * width)
                        .map_err(|e| refused(path, format!("the hand-over state: {e}")))
                })
                .transpose()?;
            let mut values = Vec::with_capacity(range.len() * width);
            for k in range.clone() {
                let row = order[k];
                match source {
                    Some(source) if !converted[k] => {
                        let at = old_offset[row] * width;
                        values.extend_from_slice(&source[at..at + width]);
                    }
                    _ => values.extend_from_slice(&fresh),
                }
            }
            out.put(format!("group.{g}.state.{j}"), values);
        }
    }
    // Each group's wave speed of the last stress update; the stage taking over computes
    // the stresses (and these) again before its first step.
    let old_speeds = c
        .arrays
        .get("stress.group_wave_speed")
        .cloned()
        .unwrap_or_default();
    let speeds = new_groups
        .iter()
        .map(|name| {
            old_groups
                .iter()
                .position(|o| o == name)
                .and_then(|og| old_speeds.get(og).copied())
                .unwrap_or(0.0)
        })
        .collect();
    out.put("stress.group_wave_speed", speeds);
    out.state = c.state.clone();
    out.set_state(CONVERTED, true.into());
    Ok(out)
}
