//! Outlines of a refined run's grid levels (`solver.refinement`), read from the scene the
//! store keeps: each finer level's region Ω^ℓ, as the solver built it (boxes grown to the
//! coarser level's elements and cut to its region), drawn as the edges between its
//! elements and the rest, in the picture's plane.

use mpm_core::refinement::Levels;
use mpm_core::scene::{Domain, Refinement};
use serde_json::Value;

/// One straight piece of a level's outline, in the picture's axes, m.
pub(crate) type Segment = [(f64, f64); 2];

/// The outline of every refined level (index 0 is level 1), clipped to `bounds`
/// (`[xmin, xmax, ymin, ymax]`, m). A 3D region is seen along `depth`: the outline of its
/// shadow, of the elements that reach into `slab` when one is given. `None` when the scene
/// names no refinement (or a `levels: []` one); an error message for a scene whose
/// refinement cannot be rebuilt.
pub(crate) fn level_outlines(
    scene: Option<&Value>,
    dim: usize,
    axes: [usize; 2],
    slab: Option<(f64, f64)>,
    bounds: [f64; 4],
) -> Result<Option<Vec<Vec<Segment>>>, String> {
    let Some(scene) = scene else {
        return Ok(None);
    };
    let Some(refinement) = scene.get("solver").and_then(|s| s.get("refinement")) else {
        return Ok(None);
    };
    if refinement.is_null() {
        return Ok(None);
    }
    let refinement: Refinement = serde_json::from_value(refinement.clone())
        .map_err(|e| format!("the stored scene's solver.refinement: {e}"))?;
    if refinement.levels.is_empty() {
        return Ok(None);
    }
    let domain: Domain = scene
        .get("domain")
        .cloned()
        .ok_or("the stored scene has no domain".to_string())
        .and_then(|d| {
            serde_json::from_value(d).map_err(|e| format!("the stored scene's domain: {e}"))
        })?;
    let outlines = match dim {
        2 => outlines(
            &refinement
                .grid_levels::<2>(&domain)
                .map_err(|e| e.to_string())?,
            axes,
            slab,
        ),
        3 => outlines(
            &refinement
                .grid_levels::<3>(&domain)
                .map_err(|e| e.to_string())?,
            axes,
            slab,
        ),
        _ => return Ok(None),
    };
    Ok(Some(
        outlines
            .into_iter()
            .map(|level| level.into_iter().filter_map(|s| clip(s, bounds)).collect())
            .collect(),
    ))
}

/// The outline of each level above the base one: the element edges with a region element
/// on one side only, of the region projected onto `axes`.
fn outlines<const D: usize>(
    levels: &Levels<D>,
    axes: [usize; 2],
    slab: Option<(f64, f64)>,
) -> Vec<Vec<Segment>> {
    let depth = (0..D).find(|d| !axes.contains(d));
    (1..levels.len())
        .map(|level| {
            let shape = levels.shape(level);
            let h = levels.level_spacing(level);
            let origin = levels.origin();
            let (na, nb) = (shape[axes[0]], shape[axes[1]]);
            // The level's elements seen in the plane: in the region at any depth (in the slab).
            let mut shadow = vec![false; na * nb];
            let mut e = [0i64; D];
            loop {
                let in_slab = match (depth, slab) {
                    (Some(d), Some((lo, hi))) => {
                        let z = origin[d] + e[d] as f64 * h;
                        z <= hi && z + h >= lo
                    }
                    _ => true,
                };
                if in_slab && levels.in_region(level, &e) {
                    shadow[e[axes[0]] as usize * nb + e[axes[1]] as usize] = true;
                }
                if !next(&mut e, &shape) {
                    break;
                }
            }
            let inside = |i: i64, j: i64| {
                i >= 0
                    && j >= 0
                    && (i as usize) < na
                    && (j as usize) < nb
                    && shadow[i as usize * nb + j as usize]
            };
            let (ox, oy) = (origin[axes[0]], origin[axes[1]]);
            let at = |i: i64, j: i64| (ox + i as f64 * h, oy + j as f64 * h);
            let mut segments = Vec::new();
            for i in 0..na as i64 {
                for j in 0..nb as i64 {
                    if !inside(i, j) {
                        continue;
                    }
                    if !inside(i - 1, j) {
                        segments.push([at(i, j), at(i, j + 1)]);
                    }
                    if !inside(i + 1, j) {
                        segments.push([at(i + 1, j), at(i + 1, j + 1)]);
                    }
                    if !inside(i, j - 1) {
                        segments.push([at(i, j), at(i + 1, j)]);
                    }
                    if !inside(i, j + 1) {
                        segments.push([at(i, j + 1), at(i + 1, j + 1)]);
                    }
                }
            }
            merge_collinear(segments)
        })
        .collect()
}

/// The next element of a box of `shape` in row-major order; false after the last.
fn next<const D: usize>(e: &mut [i64; D], shape: &[usize; D]) -> bool {
    for d in (0..D).rev() {
        e[d] += 1;
        if (e[d] as usize) < shape[d] {
            return true;
        }
        e[d] = 0;
    }
    false
}

/// Joins unit edges that continue one another on one line into one segment (fewer strokes,
/// no seams in the drawn line).
fn merge_collinear(mut segments: Vec<Segment>) -> Vec<Segment> {
    // Horizontal (same y) and vertical (same x) edges, each sorted along its line.
    let horizontal = |s: &Segment| s[0].1 == s[1].1;
    let (mut across, mut up): (Vec<Segment>, Vec<Segment>) =
        segments.drain(..).partition(horizontal);
    across.sort_by(|a, b| a[0].1.total_cmp(&b[0].1).then(a[0].0.total_cmp(&b[0].0)));
    up.sort_by(|a, b| a[0].0.total_cmp(&b[0].0).then(a[0].1.total_cmp(&b[0].1)));
    let mut merged: Vec<Segment> = Vec::new();
    for (list, along) in [(across, 0usize), (up, 1usize)] {
        let start = merged.len();
        for s in list {
            if let Some(last) = merged[start..].last_mut() {
                let same_line = if along == 0 {
                    last[1].1 == s[0].1
                } else {
                    last[1].0 == s[0].0
                };
                let touches = if along == 0 {
                    (last[1].0 - s[0].0).abs() <= 1e-9 * s[0].0.abs().max(1e-30)
                } else {
                    (last[1].1 - s[0].1).abs() <= 1e-9 * s[0].1.abs().max(1e-30)
                };
                if same_line && touches {
                    last[1] = s[1];
                    continue;
                }
            }
            merged.push(s);
        }
    }
    merged
}

/// The part of an axis-aligned segment inside `bounds`, if any.
fn clip(s: Segment, bounds: [f64; 4]) -> Option<Segment> {
    let [x0, x1, y0, y1] = bounds;
    let (mut a, mut b) = (s[0], s[1]);
    if a.1 == b.1 {
        if a.1 < y0 || a.1 > y1 {
            return None;
        }
        (a.0, b.0) = (a.0.min(b.0).max(x0), a.0.max(b.0).min(x1));
        (a.0 < b.0).then_some([a, b])
    } else {
        if a.0 < x0 || a.0 > x1 {
            return None;
        }
        (a.1, b.1) = (a.1.min(b.1).max(y0), a.1.max(b.1).min(y1));
        (a.1 < b.1).then_some([a, b])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn scene(levels: Value) -> Value {
        json!({
            "domain": { "min": [0.0, 0.0], "max": [1.0, 1.0], "cell_size": 0.1 },
            "solver": { "refinement": { "levels": levels } }
        })
    }

    #[test]
    fn one_box_is_outlined_by_four_sides_on_the_coarse_element_faces() {
        let s = scene(json!([{ "boxes": [{ "min": [0.3, 0.3], "max": [0.6, 0.5] }] }]));
        let out = level_outlines(Some(&s), 2, [0, 1], None, [-1.0, 2.0, -1.0, 2.0])
            .unwrap()
            .unwrap();
        assert_eq!(out.len(), 1);
        let sides = &out[0];
        assert_eq!(sides.len(), 4, "{sides:?}");
        // Level-0 elements have faces half a cell off the nodes (origin −0.35 with the
        // grid's padding): the box grows outward to 0.25–0.65 × 0.25–0.55.
        let xs: Vec<f64> = sides.iter().flat_map(|s| [s[0].0, s[1].0]).collect();
        let ys: Vec<f64> = sides.iter().flat_map(|s| [s[0].1, s[1].1]).collect();
        let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        for (got, want) in [
            (min(&xs), 0.25),
            (max(&xs), 0.65),
            (min(&ys), 0.25),
            (max(&ys), 0.55),
        ] {
            assert!((got - want).abs() < 1e-12, "{got} against {want}");
        }
    }

    #[test]
    fn no_refinement_or_no_levels_draws_nothing_and_a_bad_section_says_so() {
        let plain = json!({ "domain": { "min": [0.0, 0.0], "max": [1.0, 1.0], "cell_size": 0.1 } });
        assert!(
            level_outlines(Some(&plain), 2, [0, 1], None, [0.0, 1.0, 0.0, 1.0])
                .unwrap()
                .is_none()
        );
        assert!(
            level_outlines(
                Some(&scene(json!([]))),
                2,
                [0, 1],
                None,
                [0.0, 1.0, 0.0, 1.0]
            )
            .unwrap()
            .is_none()
        );
        let bad = scene(json!([{ "boxes": [{ "min": [0.3], "max": "x" }] }]));
        let e = level_outlines(Some(&bad), 2, [0, 1], None, [0.0, 1.0, 0.0, 1.0]).unwrap_err();
        assert!(e.contains("solver.refinement"), "{e}");
    }

    #[test]
    fn an_l_shaped_union_and_a_nested_level_give_their_outlines() {
        let s = scene(json!([
            { "boxes": [
                { "min": [0.3, 0.3], "max": [0.6, 0.4] },
                { "min": [0.3, 0.3], "max": [0.4, 0.6] }
            ] },
            { "boxes": [{ "min": [0.3, 0.3], "max": [0.35, 0.35] }] }
        ]));
        let out = level_outlines(Some(&s), 2, [0, 1], None, [-1.0, 2.0, -1.0, 2.0])
            .unwrap()
            .unwrap();
        assert_eq!(out.len(), 2);
        // An L has six sides; the nested level is one square.
        assert_eq!(out[0].len(), 6, "{:?}", out[0]);
        assert_eq!(out[1].len(), 4, "{:?}", out[1]);
        let length: f64 = out[0]
            .iter()
            .map(|s| (s[1].0 - s[0].0).abs() + (s[1].1 - s[0].1).abs())
            .sum();
        // 0.25–0.65 by 0.25–0.45 joined with 0.25–0.45 by 0.25–0.65: perimeter 1.6.
        assert!((length - 1.6).abs() < 1e-12, "{length}");
    }

    #[test]
    fn a_3d_region_is_drawn_as_its_shadow_or_its_slab() {
        let s = json!({
            "domain": { "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0], "cell_size": 0.1 },
            "solver": { "refinement": { "levels": [
                { "boxes": [{ "min": [0.3, 0.3, 0.3], "max": [0.6, 0.6, 0.4] }] }
            ] } }
        });
        let bounds = [-1.0, 2.0, -1.0, 2.0];
        let xy = level_outlines(Some(&s), 3, [0, 1], None, bounds)
            .unwrap()
            .unwrap();
        assert_eq!(xy[0].len(), 4);
        // Seen in xz the box is thin in z: 0.25–0.45.
        let xz = level_outlines(Some(&s), 3, [0, 2], None, bounds)
            .unwrap()
            .unwrap();
        let top = xz[0].iter().map(|s| s[0].1.max(s[1].1)).fold(0.0, f64::max);
        assert!((top - 0.45).abs() < 1e-12, "{top}");
        // A slab of xy that misses the box in z shows no level.
        let missed = level_outlines(Some(&s), 3, [0, 1], Some((0.7, 0.9)), bounds)
            .unwrap()
            .unwrap();
        assert!(missed[0].is_empty(), "{:?}", missed[0]);
    }

    #[test]
    fn segments_beyond_the_picture_are_cut_or_dropped() {
        let b = [0.0, 1.0, 0.0, 1.0];
        assert_eq!(
            clip([(-1.0, 0.5), (0.5, 0.5)], b),
            Some([(0.0, 0.5), (0.5, 0.5)])
        );
        assert_eq!(clip([(0.2, 1.5), (0.8, 1.5)], b), None);
        assert_eq!(clip([(0.5, -2.0), (0.5, -1.0)], b), None);
        assert_eq!(
            clip([(0.5, 0.2), (0.5, 3.0)], b),
            Some([(0.5, 0.2), (0.5, 1.0)])
        );
    }
}
