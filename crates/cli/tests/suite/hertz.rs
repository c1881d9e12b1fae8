//! Hertz line contact (`examples/hertz.json`): an elastic cylinder pressed into an elastic
//! block through a frictionless contact pair, 2D plane strain. The contact half-width and
//! the approach of two points near the contact are compared with Hertz's solution at the
//! load the block carries.

use crate::common;

use common::*;
use mpm_core::output::{Metrics, Outcome};
use std::f64::consts::PI;

/// Cylinder radius and the moduli of the example.
const R: f64 = 0.1;
const E_CYL: f64 = 2e6;
const E_BLOCK: f64 = 1e6;
const NU: f64 = 0.3;
/// Particle rows under the block's surface whose stress gives the half-width.
const ROWS: usize = 2;

/// The fields every frame keeps: positions, stresses and volumes (and the diagnostics).
const FIELDS: &[&str] = &["x", "stress", "volume"];

/// Plane-strain contact modulus: 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂.
fn contact_modulus() -> f64 {
    1.0 / ((1.0 - NU * NU) / E_CYL + (1.0 - NU * NU) / E_BLOCK)
}

/// Hertz half-width of a line contact under the load `p` per unit length:
/// b² = 4 P R / (π E*).
fn hertz_half_width(p: f64) -> f64 {
    (4.0 * p * R / (PI * contact_modulus())).sqrt()
}

/// McEwen's stresses (σ_x, σ_z; compression negative) on the axis at depth `z` under the
/// Hertz pressure p₀ √(1 − x²/b²) on a half-space.
fn mcewen_axis(p0: f64, b: f64, z: f64) -> (f64, f64) {
    let r = (b * b + z * z).sqrt();
    let sx = -p0 * ((b * b + 2.0 * z * z) / r - 2.0 * z) / b;
    let sz = -p0 * b / r;
    (sx, sz)
}

/// Plane-strain normal strain along the axis from (σ_x, σ_y).
fn axial_strain(sx: f64, sy: f64, e: f64) -> f64 {
    ((1.0 - NU * NU) * sy - NU * (1.0 + NU) * sx) / e
}

/// Hertz's approach of two axis points, each a distance `d` from the contact (one in the
/// block, one in the cylinder), under the load `p` per unit length: the compression of
/// the block from McEwen's half-space stresses, plus that of the cylinder, whose axis
/// stresses are McEwen's plus the Brazilian disk's far load (−2P/(π(2R − s))) and its
/// uniform tension P/(πR) (the cylinder is the half of a disk pressed between two
/// contacts; the slip platen on its diametral face is that disk's plane of symmetry).
/// Midpoint rule with 20,000 intervals.
fn hertz_approach(p: f64, d_block: f64, d_cylinder: f64) -> f64 {
    let b = hertz_half_width(p);
    let p0 = 2.0 * p / (PI * b);
    let n = 20_000;
    let mut sum = 0.0;
    let h = d_block / n as f64;
    for i in 0..n {
        let (sx, sz) = mcewen_axis(p0, b, (i as f64 + 0.5) * h);
        sum -= axial_strain(sx, sz, E_BLOCK) * h;
    }
    let h = d_cylinder / n as f64;
    for i in 0..n {
        let s = (i as f64 + 0.5) * h;
        let (sx, sz) = mcewen_axis(p0, b, s);
        let far = -2.0 * p / (PI * (2.0 * R - s));
        let tension = p / (PI * R);
        sum -= axial_strain(sx + tension, sz + far + tension, E_CYL) * h;
    }
    sum
}

/// The half-width b of the profile p₀ √(1 − x²/b²) (zero beyond b) that fits the
/// pressures `(x, p)` best in least squares, searched on a grid of dx/100 up to R; for
/// each b the best p₀ is Σ p s / Σ s².
fn fit_half_width(points: &[(f64, f64)], dx: f64) -> f64 {
    let mut best = (f64::INFINITY, 0.0);
    let steps = (R / (dx / 100.0)) as usize;
    for k in 1..=steps {
        let b = k as f64 * dx / 100.0;
        let shape = |x: f64| (1.0 - (x / b).powi(2)).max(0.0).sqrt();
        let (mut ps, mut ss) = (0.0, 0.0);
        for &(x, p) in points {
            ps += p * shape(x);
            ss += shape(x).powi(2);
        }
        if ss == 0.0 {
            continue;
        }
        let p0 = ps / ss;
        let residual: f64 = points
            .iter()
            .map(|&(x, p)| (p - p0 * shape(x)).powi(2))
            .sum();
        if residual < best.0 {
            best = (residual, b);
        }
    }
    best.1
}

/// One frame's measurements.
struct Measured {
    time: f64,
    /// Load per unit length of the full cylinder, from the block's stresses.
    load: f64,
    /// The same from the cylinder's stresses.
    load_cylinder: f64,
    /// Half-width from the second moment of the block's top rows' normal stress.
    half_width: f64,
    /// Approach of the axis points `d` from the contact.
    approach: f64,
    /// Distances of the two axis points from the contact line.
    d_block: f64,
    d_cylinder: f64,
}

fn measure(frames: &FieldFrames, k: usize, blocks: usize, dx: f64, h: f64) -> Measured {
    let x0 = &frames.values[0][0];
    let (x, s, v) = (
        &frames.values[0][k],
        &frames.values[1][k],
        &frames.values[2][k],
    );
    let n = v.len();
    // Every horizontal section of the block (no body force) carries the load, so the
    // volume integral of σ_yy is −P times the height; the same over the cylinder's R.
    let sum = |r: std::ops::Range<usize>| r.map(|p| v[p] * s[4 * p + 3]).sum::<f64>();
    let load = -sum(0..blocks) / h;
    let load_cylinder = -sum(blocks..n) / R;
    // Half-width: the Hertz profile p₀ √(1 − x²/b²) fitted to the normal stress of each
    // of the block's top particle rows (least squares over b on a grid of dx/100, p₀
    // linear); the mean over the rows. Rows at depth dx/4 and 3dx/4.
    let mut widths = Vec::new();
    for row in 0..ROWS {
        let z = (row as f64 + 0.5) * dx / 2.0;
        let points: Vec<(f64, f64)> = (0..blocks)
            .filter(|&p| (h - x0[2 * p + 1] - z).abs() < dx / 8.0)
            .map(|p| (x[2 * p], -s[4 * p + 3]))
            .collect();
        widths.push(fit_half_width(&points, dx));
    }
    let half_width = widths.iter().sum::<f64>() / widths.len() as f64;
    // Approach: the particle column at x = dx/4, the rows nearest a quarter radius from
    // the contact on either side.
    let target = R / 4.0;
    let pick = |range: std::ops::Range<usize>, sign: f64| {
        range
            .filter(|&p| x0[2 * p] > 0.0 && x0[2 * p] < dx / 2.0)
            .min_by(|&a, &b| {
                let da = (sign * (x0[2 * a + 1] - h) - target).abs();
                let db = (sign * (x0[2 * b + 1] - h) - target).abs();
                da.partial_cmp(&db).unwrap()
            })
            .unwrap()
    };
    let pb = pick(0..blocks, -1.0);
    let pc = pick(blocks..n, 1.0);
    let d_block = h - x0[2 * pb + 1];
    let d_cylinder = x0[2 * pc + 1] - h;
    let approach = (x[2 * pb + 1] - x0[2 * pb + 1]) - (x[2 * pc + 1] - x0[2 * pc + 1]);
    Measured {
        time: frames.times[k],
        load,
        load_cylinder,
        half_width,
        approach,
        d_block,
        d_cylinder,
    }
}

/// The cell size: `HERTZ_DX` or the example's 5 mm (R = 20 cells).
fn cell_size() -> f64 {
    std::env::var("HERTZ_DX")
        .ok()
        .map(|s| s.parse().expect("HERTZ_DX is a number"))
        .unwrap_or(0.005)
}

/// Runs the example with `overrides` (and `HERTZ_SET`, space-separated `PATH=VALUE`s) at
/// cell `dx`; prints and returns every frame's measurements after the first, and the
/// metrics.
fn run_hertz(dx: f64, overrides: &[&str]) -> (Metrics, Vec<Measured>) {
    let mut all = vec![format!("domain.cell_size={dx}")];
    all.extend(overrides.iter().map(|s| s.to_string()));
    if let Ok(extra) = std::env::var("HERTZ_SET") {
        all.extend(extra.split(' ').map(String::from));
    }
    let scene = load(&example("hertz.json"), &all);
    let blocks = scene.bodies[0].volumes.len();
    // The block's top face is the contact line.
    let block_height = match &scene.scene.bodies[0].shape {
        mpm_core::scene::Shape::Box { max, .. } => max[1],
        _ => panic!("the block is a box"),
    };
    let (m, frames) = run_fields(&scene, FIELDS);
    println!(
        "cell {dx} m: {:?}, {} steps, {:.1} s, energy drift {:.3}",
        m.outcome, m.steps, m.wall_seconds, m.energy_drift
    );
    let mut measured = Vec::new();
    for k in 1..frames.times.len() {
        let f = measure(&frames, k, blocks, dx, block_height);
        let b = hertz_half_width(f.load);
        let a = hertz_approach(f.load, f.d_block, f.d_cylinder);
        println!(
            "t {:.3} s  P {:7.1} N/m (cylinder {:7.1})  b {:.5} m, Hertz {:.5} ({:+.2} cells)  approach {:.6} m, Hertz {:.6} ({:+.1}%)  d {:.5}/{:.5} m  kinetic {:.2e} J",
            f.time,
            f.load,
            f.load_cylinder,
            f.half_width,
            b,
            (f.half_width - b) / dx,
            f.approach,
            a,
            100.0 * (f.approach / a - 1.0),
            f.d_block,
            f.d_cylinder,
            frames.diagnostics[k][2],
        );
        measured.push(f);
    }
    (m, measured)
}

/// The half-width and the approach against Hertz within 25%, in every frame where the
/// load is 1000 N/m or more (b ≥ 2.6 cells at the example's cell).
///
/// Both bounds keep a finding from growing rather than verify. Over those frames the
/// fitted half-width is 7–23% below Hertz's at 5 mm and −18% to +13% off at 2.5 mm (the
/// fit follows the particle rows' stress, which the quadratic B-spline spreads over
/// three cells), and the approach −9% to +18% and +1% to +13% off, growing with the load
/// at both cells and the same with a block twice as wide and deep (README, Hertz): not
/// the cell and not the block's size. The contact's gap test is most of it: rebuilt with
/// `GAP_TOLERANCE` 0.02 and 0.1 the last frame gave b / Hertz 0.91 and 1.19 and approach /
/// Hertz 1.087 and 0.963 (0.80 and 1.145 at 0).
#[test]
fn cylinder_on_a_block_matches_hertz() {
    let dx = cell_size();
    let (m, measured) = run_hertz(dx, &[]);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    // Energy balance closed with the platen's work (measured −0.037).
    assert!(
        m.energy_drift.abs() < 0.1,
        "energy drift {}",
        m.energy_drift
    );
    let loaded: Vec<&Measured> = measured.iter().filter(|f| f.load >= 1000.0).collect();
    assert!(loaded.len() >= 5, "only {} loaded frames", loaded.len());
    for f in loaded {
        let b = hertz_half_width(f.load);
        assert!(
            (f.half_width / b - 1.0).abs() < 0.25,
            "t {}: half-width {} against Hertz {b}",
            f.time,
            f.half_width
        );
        let a = hertz_approach(f.load, f.d_block, f.d_cylinder);
        assert!(
            (f.approach / a - 1.0).abs() < 0.25,
            "t {}: approach {} against Hertz {a}",
            f.time,
            f.approach
        );
    }
}

/// The half model (a symmetry wall at x = 0 through the contact) must behave as the full
/// model. It gained energy (drift +0.83 where the full model's is −0.037) until the contact
/// step mirrored the ghost nodes behind stick and symmetry walls again after the contact
/// laws had changed the velocities in front of them (G2P read stale ghost velocities), and
/// folded the image body's particle volume and mass gradient across symmetry walls (the
/// gap test and the normal at the plane). Measured: the same drift as the full model.
#[test]
fn a_symmetry_wall_through_the_contact_keeps_the_energy_balance() {
    let (m, _) = run_hertz(
        cell_size(),
        &[
            "domain.min=[0,0]",
            r#"domain.walls=[{"sides":["x-"],"condition":"symmetry"},{"sides":["y-"],"condition":"stick"}]"#,
            "bodies[0].shape.box.min=[0,0]",
            "stop.max_energy_growth=100",
        ],
    );
    assert!(
        m.energy_drift.abs() < 0.1,
        "energy drift {}",
        m.energy_drift
    );
}
