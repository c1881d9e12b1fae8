//! Bonded interfaces that can delaminate (the `cohesive` contact law): a double cantilever
//! beam opened at its end follows beam theory for the given G_Ic (load against opening,
//! crack length against opening); the cohesive dissipation is G_Ic times the crack growth;
//! the law's settings are checked with JSON paths.

use crate::common;

use common::*;
use mpm_core::output::{Metrics, Outcome};
use mpm_core::scene::ValidatedScene;
use serde_json::{Value, json};

/// Runs `scene` keeping positions, stress and interface damage (`values[0..3]`).
fn run_frames(scene: &ValidatedScene) -> (Metrics, FieldFrames) {
    run_fields(scene, &["x", "stress", "interface_damage"])
}

/// The double cantilever beam of the test, in SI units, per metre of thickness (plane
/// strain): two arms of thickness `h` and length `length`, bonded along y = `y0` beyond
/// the precrack, pinned at `x_load` on their mid-planes and pulled apart at `speed`.
struct Dcb {
    dx: f64,
    h: f64,
    x0: f64,
    length: f64,
    y0: f64,
    x_load: f64,
    /// The initial crack tip (nominal; `tip()` puts it half a cell before a node).
    tip: f64,
    speed: f64,
    end_time: f64,
    youngs: f64,
    poisson: f64,
    strength: f64,
    energy: f64,
}

impl Dcb {
    fn coarse() -> Self {
        Self {
            dx: 0.0025,
            h: 0.01,
            x0: 0.005,
            length: 0.1,
            y0: 0.02,
            x_load: 0.0075,
            tip: 0.03625,
            speed: 0.1,
            end_time: 0.025,
            youngs: 1e9,
            poisson: 0.3,
            strength: 1.5e6,
            energy: 100.0,
        }
    }

    /// The coarse beam with `DCB_DX` (cell size) and `DCB_STRENGTH` (normal and shear
    /// strength) from the environment when set.
    fn from_env() -> Self {
        let mut dcb = Self::coarse();
        let var = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f64>().ok());
        if let Some(dx) = var("DCB_DX") {
            dcb.dx = dx;
        }
        if let Some(strength) = var("DCB_STRENGTH") {
            dcb.strength = strength;
        }
        if let Some(end) = var("DCB_END_TIME") {
            dcb.end_time = end;
        }
        dcb
    }

    /// The initial crack tip: between the last precracked and the first bonded node, the
    /// half cell nearest the nominal tip (a node carries the interface half a cell either
    /// side of it).
    fn tip(&self) -> f64 {
        ((self.tip / self.dx - 0.5).round() + 0.5) * self.dx
    }

    /// Plane-strain modulus times the arm's second moment of area (per unit width).
    fn bending_stiffness(&self) -> f64 {
        self.youngs / (1.0 - self.poisson * self.poisson) * self.h.powi(3) / 12.0
    }

    fn scene(&self) -> Value {
        let (dx, h, y0) = (self.dx, self.h, self.y0);
        let x1 = self.x0 + self.length;
        // The pins: one grid node each on an arm's mid-plane, held by a stick obstacle that
        // keeps enclosing it (and no other node) while it moves less than a cell.
        let pin = |name: &str, y: f64, v: f64| {
            let (lo, hi) = if v > 0.0 {
                (y - 0.9 * dx, y + 0.08 * dx)
            } else {
                (y - 0.08 * dx, y + 0.9 * dx)
            };
            json!({"name": name, "shape": {"box": {"min": [self.x_load - 0.04 * dx, lo], "max": [self.x_load + 0.04 * dx, hi]}},
                   "condition": "stick", "velocity": [0.0, v]})
        };
        json!({
            "name": "dcb", "dimension": 2,
            "domain": {"min": [0, 0], "max": [x1 + 4.0 * dx, y0 + h + 4.0 * dx], "cell_size": dx},
            "solver": {"end_time": self.end_time, "kernel": "bspline2", "transfer": "apic", "cfl": 0.5},
            "materials": {"arm": {"type": "linear_elastic", "density": 1000.0,
                                  "youngs_modulus": self.youngs, "poisson_ratio": self.poisson}},
            "bodies": [
                {"name": "lower", "material": "arm", "shape": {"box": {"min": [self.x0, y0 - h], "max": [x1, y0]}}},
                {"name": "upper", "material": "arm", "shape": {"box": {"min": [self.x0, y0], "max": [x1, y0 + h]}}}],
            "obstacles": [pin("upper pin", y0 + 0.5 * h, 0.5 * self.speed),
                          pin("lower pin", y0 - 0.5 * h, -0.5 * self.speed)],
            "contact": {"pairs": [{"bodies": ["lower", "upper"],
                "law": {"cohesive": {"normal_strength": self.strength, "shear_strength": self.strength,
                                     "mode_i_energy": self.energy, "mode_ii_energy": 2.0 * self.energy}},
                "precrack": {"box": {"min": [0.0, y0 - 2.0 * dx], "max": [self.tip(), y0 + 2.0 * dx]}}}]},
            "output": {"frames": 60, "fields": ["x", "v", "stress", "interface_damage"]}
        })
    }
}

/// The shear force carried by the upper arm between the pin and the initial crack tip
/// (Σ σ_xy V_p over a strip, divided by its length): the load on the pin.
fn pin_load(dcb: &Dcb, frames: &FieldFrames, k: usize) -> f64 {
    let (from, to) = (dcb.x_load + 0.005, dcb.tip() - 0.005);
    let volume = dcb.dx * dcb.dx / 4.0;
    let x = &frames.values[0][k];
    let s = &frames.values[1][k];
    let sum: f64 = (0..x.len() / 2)
        .filter(|&p| x[2 * p] > from && x[2 * p] < to && x[2 * p + 1] > dcb.y0)
        .map(|p| s[4 * p + 1] * volume)
        .sum();
    -sum / (to - from)
}

/// The load-line opening in every frame: the change in distance between the mean heights
/// of the two arms' particles within a cell of the pins (the arms' deflection there, not
/// the pins' travel, which adds the local indentation of a point load: logarithmic in
/// the cell size in 2D).
fn openings(dcb: &Dcb, frames: &FieldFrames) -> Vec<f64> {
    let x0 = &frames.values[0][0];
    let near: Vec<(usize, bool)> = (0..x0.len() / 2)
        .filter(|&p| (x0[2 * p] - dcb.x_load).abs() <= dcb.dx)
        .map(|p| (p, x0[2 * p + 1] > dcb.y0))
        .collect();
    let gap = |x: &[f64]| {
        let mean = |upper: bool| {
            let ys: Vec<f64> = near
                .iter()
                .filter(|(_, u)| *u == upper)
                .map(|(p, _)| x[2 * p + 1])
                .collect();
            ys.iter().sum::<f64>() / ys.len() as f64
        };
        mean(true) - mean(false)
    };
    let start = gap(x0);
    frames.values[0].iter().map(|x| gap(x) - start).collect()
}

/// The last row of the `cohesive` table at or before `time` (the first row before it):
/// time, debonded length, damaged nodes, debonded nodes, energy dissipated.
fn cohesive_row(m: &Metrics, time: f64) -> &[f64] {
    let rows = &m.tables["cohesive"].rows;
    rows.iter()
        .take_while(|r| r[0] <= time)
        .last()
        .unwrap_or(&rows[0])
}

/// The debonded length at `time`.
fn debonded(m: &Metrics, time: f64) -> f64 {
    cohesive_row(m, time)[1]
}

/// What the DCB run measured against beam theory.
struct DcbResult {
    /// The crack length the initial compliance gives (corrected beam theory), minus the
    /// nominal initial crack length, m.
    tip_offset: f64,
    /// Energy release rates over the frames after the crack first grew, from the load and
    /// the load-line opening (compliance method), J/m².
    release: Vec<f64>,
    /// Damage-based crack length minus beam theory's for the opening, in the frames after
    /// the crack first grew, m.
    length_error: Vec<f64>,
    /// The same for the energy-equivalent crack length `a0 + dissipated / G_Ic`, m.
    equivalent_error: Vec<f64>,
    /// G in the frames before the crack grew, J/m².
    release_before: Vec<f64>,
    /// Energy dissipated by the interface, J, and G_Ic times the debonded length, J.
    dissipated: f64,
    debonded_energy: f64,
    /// The largest `interface_damage` in the last frame of the particles on the
    /// precracked interface, of those on the bonded interface at the far end, and of those
    /// beyond the kernel's reach (2.5 cells) from the interface nodes.
    damage: [f64; 3],
    metrics: Metrics,
}

/// Runs `dcb` and compares it with corrected beam theory (plane strain, per unit width):
/// an arm of crack length `a` bends as a cantilever of length `a + 0.64 h` (Kanninen's
/// root rotation), so the load-line opening is `δ = 2 P (a + χ)³ / (3 E'I)` and the
/// energy release rate `G = P² (a + χ)² / (E'I)`; eliminating `a + χ`,
/// `G = 3 P δ / (2 (3 E'I δ / (2 P))^(1/3))` needs only the load and the opening.
fn run_dcb(dcb: &Dcb) -> DcbResult {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_scene_value(dir.path(), &dcb.scene());
    let (m, frames) = run_frames(&scene);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let ei = dcb.bending_stiffness();
    let chi = 0.64 * dcb.h;
    let a0 = dcb.tip() - dcb.x_load;
    let start = debonded(&m, 0.0);
    let opening = openings(dcb, &frames);
    // Before the crack grows: the opening at which beam theory's G reaches G_Ic.
    let initiation = 2.0 * (dcb.energy / ei).sqrt() * (a0 + chi).powi(2) / 3.0;
    let mut compliance = (0.0, 0.0);
    let mut release = Vec::new();
    let mut length_error = Vec::new();
    let mut equivalent_error = Vec::new();
    let mut release_before = Vec::new();
    println!("t, opening, load, G, crack length, energy-equivalent, beam theory");
    for (k, &t) in frames.times.iter().enumerate() {
        let (delta, p) = (opening[k], pin_load(dcb, &frames, k));
        if k == 0 {
            continue;
        }
        let a = a0 + (debonded(&m, t) - start);
        let arm = (1.5 * ei * delta / p).cbrt();
        let g = 1.5 * p * delta / arm;
        let a_theory = ((1.5 * delta * (ei / dcb.energy).sqrt()).sqrt() - chi).max(a0);
        let a_equivalent = a0 + cohesive_row(&m, t)[4] / dcb.energy;
        println!("{t:.5} {delta:.3e} {p:8.1} {g:6.1} {a:.5} {a_equivalent:.5} {a_theory:.5}");
        if delta < 0.5 * initiation {
            compliance.0 += delta * p;
            compliance.1 += p * p;
        }
        if a > a0 {
            release.push(g);
            length_error.push(a - a_theory);
            equivalent_error.push(a_equivalent - a_theory);
        } else {
            release_before.push(g);
        }
    }
    let mut damage = [0.0f64; 3];
    let (x0, last) = (&frames.values[0][0], frames.values[2].last().unwrap());
    for (p, d) in last.iter().enumerate() {
        let (x, y) = (x0[2 * p], x0[2 * p + 1]);
        let near = (y - dcb.y0).abs() < dcb.dx;
        let group = if near && x > dcb.x_load + dcb.dx && x < dcb.tip() - dcb.dx {
            0
        } else if near && x > dcb.x0 + dcb.length - 0.02 {
            1
        } else if (y - dcb.y0).abs() > 2.5 * dcb.dx {
            2
        } else {
            continue;
        };
        damage[group] = damage[group].max(*d);
    }
    let c = compliance.0 / compliance.1;
    let tip_offset = (1.5 * ei * c).cbrt() - chi - a0;
    let dissipated = m.physics["contact.cohesive_dissipation"];
    let debonded_energy = dcb.energy * (debonded(&m, f64::INFINITY) - start);
    DcbResult {
        tip_offset,
        release,
        length_error,
        equivalent_error,
        release_before,
        dissipated,
        debonded_energy,
        damage,
        metrics: m,
    }
}

/// The mean of `x`.
fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

/// The smallest and largest of `x`.
fn range(x: &[f64]) -> (f64, f64) {
    x.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        })
}

#[test]
fn double_cantilever_beam_follows_beam_theory_for_g_ic() {
    let dcb = Dcb::from_env();
    let r = run_dcb(&dcb);
    let gc = dcb.energy;
    let (g_min, g_max) = range(&r.release);
    let (e_min, e_max) = range(&r.length_error);
    let (q_min, q_max) = range(&r.equivalent_error);
    let before = range(&r.release_before).1;
    let onset = *r.release_before.last().unwrap();
    // The cohesive zone of a slender DCB arm (Turon et al. 2007): (E' G_Ic h³ / σc²)^¼.
    let e_prime = dcb.youngs / (1.0 - dcb.poisson * dcb.poisson);
    let zone = (e_prime * gc * dcb.h.powi(3) / dcb.strength.powi(2)).powf(0.25);
    println!(
        "dx {}: initial crack tip {:+.2} cells from nominal (compliance); G before growth up to {before:.1}, {onset:.1} in the last frame before; while growing mean {:.1}, {g_min:.1} to {g_max:.1} J/m² (G_Ic {gc}) over {} frames; debonded crack length − beam theory {:+.2} to {:+.2} cells (cohesive zone {:.1} cells); energy-equivalent crack length − beam theory {:+.2} to {:+.2} cells; dissipated {:.4} J, G_Ic × debonded {:.4} J; damage {:?}; energy drift {:.4}; {} steps, {:.1} s",
        dcb.dx,
        r.tip_offset / dcb.dx,
        mean(&r.release),
        r.release.len(),
        e_min / dcb.dx,
        e_max / dcb.dx,
        zone / dcb.dx,
        q_min / dcb.dx,
        q_max / dcb.dx,
        r.dissipated,
        r.debonded_energy,
        r.damage,
        r.metrics.energy_drift,
        r.metrics.steps,
        r.metrics.wall_seconds
    );
    assert!(r.release.len() >= 10, "the crack hardly grew");
    // A node carries the interface half a cell either side of it, so the precrack's tip is
    // known to within a cell: the initial compliance puts it 0.78 cells beyond the
    // nominal tip (0.92 of the half-size cell, 1.15 mm against 1.95 mm).
    assert!(r.tip_offset.abs() < dcb.dx, "tip offset {}", r.tip_offset);
    // The crack grows when G = G_Ic: below 1.15 G_Ic before it grows (measured 1.061 in
    // the last frame before), and G stays within 15% of G_Ic while it grows (measured +3
    // to +11%, mean +7.2%; +2 to +7%, mean +4.1% with half the cell size: the excess is
    // the cohesive zone's resolution, 6 cells here).
    assert!(
        before < 1.15 * gc && onset > 0.85 * gc,
        "G {before}, {onset}"
    );
    assert!(
        g_min > 0.85 * gc && g_max < 1.15 * gc,
        "G while growing {g_min} to {g_max}"
    );
    assert!((mean(&r.release) - gc).abs() < 0.1 * gc);
    // Crack length against beam theory's for the opening: the debonded tip trails the
    // equivalent elastic crack by part of the cohesive zone (measured 2.4 to 3.2 cells,
    // 6.0 to 7.9 mm; 5.6 to 6.7 mm with half the cell size), and is never ahead of it by
    // more than a cell. The energy-equivalent crack length a0 + dissipated / G_Ic is within
    // two cells (it counts the partly damaged nodes).
    assert!(
        e_min > -zone && e_max < dcb.dx,
        "debonded crack length error {e_min} to {e_max} (zone {zone})"
    );
    assert!(
        q_min > -2.0 * dcb.dx && q_max < 2.0 * dcb.dx,
        "energy-equivalent crack length error {q_min} to {q_max}"
    );
    // Dissipation: G_Ic times the debonded length plus what the damaged zone took.
    assert!(
        r.dissipated > r.debonded_energy && r.dissipated < r.debonded_energy + gc * zone,
        "dissipated {} J, G_Ic × debonded {} J",
        r.dissipated,
        r.debonded_energy
    );
    // With the dissipation counted as work, the energy balance closes (measured −0.021).
    assert!(
        r.metrics.energy_drift.abs() < 0.05,
        "{}",
        r.metrics.energy_drift
    );
    // The damage field: 1 on the precrack, 0 on the far bonded interface and away from it.
    assert_eq!(r.damage, [1.0, 0.0, 0.0]);
}

/// Whether two JSON values are equal, numbers to 1e-12 relative.
fn same(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            (x - y).abs() <= 1e-12 * x.abs().max(y.abs())
        }
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same(v, w)))
        }
        _ => a == b,
    }
}

#[test]
fn dcb_example_is_the_tested_beam() {
    let text = std::fs::read_to_string(example("dcb.json")).unwrap();
    let mut example: Value = serde_json::from_str(&text).unwrap();
    example.as_object_mut().unwrap().remove("description");
    let tested = Dcb::coarse().scene();
    assert!(same(&example, &tested), "{example:#}\n{tested:#}");
}

/// Writes `scene` to `dir` and loads it.
fn load_scene_value(dir: &std::path::Path, scene: &Value) -> ValidatedScene {
    load(&write_scene(dir, "scene.json", scene), &[])
}

#[test]
fn cohesive_law_problems_name_their_paths() {
    let issues = invalid_example(
        "dcb.json",
        &[
            "contact.pairs[0].law.cohesive.normal_strength=-1",
            "contact.pairs[0].law.cohesive.mode_ii_energy=0",
            "contact.pairs[0].law.cohesive.mixed_mode_exponent=0.5",
            "contact.pairs[0].law.cohesive.friction=-0.1",
        ],
    );
    for path in [
        "normal_strength",
        "mode_ii_energy",
        "mixed_mode_exponent",
        "friction",
    ] {
        let at = format!("contact.pairs[0].law.cohesive.{path}:");
        assert!(issues.iter().any(|i| i.starts_with(&at)), "{at} {issues:?}");
    }
    // A precrack needs a cohesive law, and so does the damage field.
    let issues = invalid_example("dcb.json", &["contact.pairs[0].law=\"frictionless\""]);
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("contact.pairs[0].precrack: only a `cohesive` law")),
        "{issues:?}"
    );
    assert!(
        issues
            .iter()
            .any(|i| i.starts_with("output.fields[3]: unknown field `interface_damage`")),
        "{issues:?}"
    );
    // Mixed-mode criteria other than the power law (Benzeggagh–Kenane) are refused.
    let issues = invalid_example(
        "dcb.json",
        &["contact.pairs[0].law.cohesive.mixed_mode=\"bk\""],
    );
    println!("{issues:?}");
    assert!(
        issues.iter().any(|i| i.contains("mixed_mode")),
        "{issues:?}"
    );
}

/// Two blocks bonded face to face, thrown apart at 2 m/s, with a cohesive interface of
/// strength `strength` and fracture energies `energy`, in `dimension` dimensions; the
/// interface is 0.4 m long (2D) or 0.4 × 0.4 m² (3D).
fn thrown_apart(dimension: usize, strength: f64, energy: f64) -> Value {
    let corner = |x: f64, y: f64| -> Value {
        if dimension == 2 {
            json!([x, y])
        } else {
            json!([x, y, x])
        }
    };
    let velocity = |v: f64| -> Value {
        if dimension == 2 {
            json!([0.0, v])
        } else {
            json!([0.0, v, 0.0])
        }
    };
    // Four cells through each block: the area estimate needs three or more.
    let (max, cell) = if dimension == 2 {
        (json!([1.0, 0.5]), 0.025)
    } else {
        (json!([1.0, 0.5, 1.0]), 0.025)
    };
    json!({
        "name": "bonded-blocks", "dimension": dimension,
        "domain": {"min": corner(0.0, 0.0), "max": max, "cell_size": cell},
        "solver": {"end_time": 0.05, "cfl": 0.5},
        "materials": {"rubber": {"type": "neo_hookean", "density": 1000.0,
                                 "youngs_modulus": 1e6, "poisson_ratio": 0.3}},
        "bodies": [
            {"name": "lower", "material": "rubber",
             "shape": {"box": {"min": corner(0.3, 0.1), "max": corner(0.7, 0.2)}},
             "velocity": {"uniform": velocity(-1.0)}},
            {"name": "upper", "material": "rubber",
             "shape": {"box": {"min": corner(0.3, 0.2), "max": corner(0.7, 0.3)}},
             "velocity": {"uniform": velocity(1.0)}}],
        "contact": {"pairs": [{"bodies": ["lower", "upper"], "law": {"cohesive": {
            "normal_strength": strength, "shear_strength": strength,
            "mode_i_energy": energy, "mode_ii_energy": energy}}}]},
        "output": {"frames": 2, "fields": ["x", "interface_damage"]}
    })
}

#[test]
fn a_weak_bond_debonds_its_whole_interface_and_the_areas_add_up() {
    let dir = tempfile::tempdir().unwrap();
    for (dimension, expected) in [(2, 0.4), (3, 0.16)] {
        let scene = load_scene_value(dir.path(), &thrown_apart(dimension, 1e3, 1e-3));
        let m = run(&scene);
        assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
        let last = m.tables["cohesive"].rows.last().unwrap().clone();
        let dissipated = m.physics["contact.cohesive_dissipation"];
        let interface = m.physics["contact.cohesive_interface"];
        println!(
            "{dimension}D: interface {interface} (geometry {expected}), debonded {}, {} nodes; dissipated {dissipated} J (G_c × area {}); momentum {}",
            last[1],
            last[3],
            1e-3 * expected,
            m.max_momentum
        );
        // The nodes' areas add up to the interface's (measured −0.17% in 2D, −0.73% in
        // 3D, where the four corner nodes, a quarter full, do not bond), and every node of
        // the interface debonds.
        assert!(
            (interface - expected).abs() < 0.01 * expected,
            "{dimension}D: interface {interface} of {expected}"
        );
        assert!(
            (last[1] - interface).abs() < 1e-12 * interface,
            "{dimension}D: debonded {}",
            last[1]
        );
        // Each node opens far beyond 2 G_c / σc (2e-6 m) in its first step; each mode may
        // not dissipate more than G_c times the node's area (without that cap they
        // dissipated 650 times as much: the step's whole opening at the strength). The
        // Poisson contraction shears the interface's ends as well: mixed mode, for which
        // the power-law criterion (α = 2) allows up to √2 G_c. Measured 1.047 (2D) and 1.084 (3D).
        let ratio = dissipated / (1e-3 * last[1]);
        assert!(
            (1.0..std::f64::consts::SQRT_2).contains(&ratio),
            "{dimension}D: dissipated {ratio} G_c × debonded"
        );
        // The bond's impulses are equal and opposite.
        assert!(m.max_momentum < 1e-9, "momentum {}", m.max_momentum);
    }
}

/// The block on the inclined elastic slab of `contact.rs` (gravity tilted by `angle`
/// degrees), bonded to it by a cohesive interface of strength `strength` and fracture
/// energies `energy`, Coulomb friction `mu` once debonded.
fn bonded_incline(angle: f64, strength: f64, energy: f64, mu: f64) -> Value {
    let law = json!({"cohesive": {
        "normal_strength": strength, "shear_strength": strength,
        "mode_i_energy": energy, "mode_ii_energy": energy, "friction": mu}});
    incline_scene(angle, law, &["x", "stress", "interface_damage"])
}

/// The block's mean acceleration along the slope over `t ≥ 0.1` s (second differences of
/// its mean position between frames), its largest displacement and the run's metrics.
fn block_acceleration(scene: &Value) -> (f64, f64, Metrics) {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_scene_value(dir.path(), scene);
    let (m, frames) = run_frames(&scene);
    assert_eq!(m.outcome, Some(Outcome::Finished), "{:?}", m.diagnostic);
    let x0 = &frames.values[0][0];
    let block: Vec<usize> = (0..x0.len() / 2).filter(|&p| x0[2 * p + 1] > 0.1).collect();
    let mean_x: Vec<f64> = frames.values[0]
        .iter()
        .map(|x| block.iter().map(|&p| x[2 * p]).sum::<f64>() / block.len() as f64)
        .collect();
    // Second differences of the mean position over equal frame intervals, averaged.
    let dt = frames.times[1] - frames.times[0];
    let accelerations: Vec<f64> = mean_x
        .windows(3)
        .zip(&frames.times)
        .filter(|(_, t)| **t >= 0.1)
        .map(|(w, _)| (w[2] - 2.0 * w[1] + w[0]) / (dt * dt))
        .collect();
    let moved = mean_x
        .iter()
        .map(|x| (x - mean_x[0]).abs())
        .fold(0.0, f64::max);
    (mean(&accelerations), moved, m)
}

#[test]
fn a_debonded_block_slides_with_coulomb_friction_and_a_bonded_one_holds() {
    let (angle, mu) = (30.0f64, 0.3);
    let (s, c) = angle.to_radians().sin_cos();
    // Weak bond (shear strength 100 Pa against about 390 Pa of shear under the block):
    // debonded at once, then Coulomb friction.
    let (a, _, m) = block_acceleration(&bonded_incline(angle, 100.0, 1e-3, mu));
    let expected = 9.81 * (s - mu * c);
    let friction = m.physics["contact.friction_work"];
    println!(
        "debonded: a = {a:.4} m/s², g(sin θ − μ cos θ) = {expected:.4}; friction work {friction:.3} J, cohesive dissipation {:.2e} J (with the friction of the softening steps), energy drift {:.2e}; table {:?}",
        m.physics["contact.cohesive_dissipation"],
        m.energy_drift,
        &m.tables["cohesive"].rows.last()
    );
    // 2% (measured −0.27%, as with the contact law's friction in contact.rs); friction
    // work counted, the energy balance closes (measured −2.4e-3).
    assert!((a - expected).abs() < 0.02 * expected, "a = {a}");
    assert!(friction > 0.0);
    assert!(
        m.energy_drift.abs() < 0.01,
        "energy drift {}",
        m.energy_drift
    );
    // Strong bond, no friction: the block stays where it is (it would slide 0.6 m), only
    // the elastic shear of the block and slab moves it; no node is damaged.
    let (a, moved, m) = block_acceleration(&bonded_incline(angle, 1e5, 1e3, 0.0));
    let free = 9.81 * s;
    println!(
        "bonded: a = {a:.5} m/s² (free sliding {free:.3}), moved {moved:.2e} m; table {:?}",
        &m.tables["cohesive"].rows.last()
    );
    assert!(moved < 1e-3, "moved {moved} m");
    assert_eq!(m.tables["cohesive"].rows.last().unwrap()[2..4], [0.0, 0.0]);
}
