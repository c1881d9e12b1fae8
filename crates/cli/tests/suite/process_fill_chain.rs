//! The underfill process from the fill on (`examples/underfill-process-2d.json`): the fill
//! stage's liquid becomes the cure stage's underfill where it is, with its temperature and
//! cure, and the air it trapped becomes empty space of the measured size and place.

use crate::common;

use common::{example, run_scene_json};
use mpm_io::ResultStore;
use serde_json::{Value, json};

fn process_scene() -> Value {
    serde_json::from_str(&std::fs::read_to_string(example("underfill-process-2d.json")).unwrap())
        .unwrap()
}

/// Index of a material in the `material` output field (the scene's materials in name
/// order).
const UNDERFILL: f64 = 3.0;

#[test]
fn the_fill_hands_its_liquid_and_its_void_to_the_cure() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = process_scene();
    // The fill and the first five minutes of the cure.
    let mut stages = s["stages"].as_array().unwrap()[..2].to_vec();
    stages[1]["changes"]["solver"]["end_time"] = json!(300.0);
    stages[1]["changes"]["output"]["frames"] = json!(2);
    s["stages"] = Value::Array(stages);
    let metrics = run_scene_json(dir.path(), "chain", &s);
    let fill = &metrics["stages"][0];
    let cure = &metrics["stages"][1];
    assert_eq!(fill["outcome"], "finished");
    assert_eq!(cure["outcome"], "finished");
    let store = |stage: &str| {
        ResultStore::open(dir.path().join("chain/underfill-process-2d.zarr"))
            .unwrap()
            .stage(stage)
            .unwrap()
    };
    let (fill_store, cure_store) = (store("fill"), store("cure"));
    let last = fill_store.frame_count().unwrap() - 1;
    let field = |s: &ResultStore, name: &str, frame: u64| s.frame(name, frame).unwrap().1;
    let (x, liquid, material) = (
        field(&fill_store, "x", last),
        field(&fill_store, "fill", last),
        field(&fill_store, "material", last),
    );
    // The air the fill trapped: the void table's area, and its area-weighted centre.
    let (columns, rows) = fill_store.table("underfill_voids").unwrap().unwrap();
    let col = |name: &str| columns.iter().position(|c| c == name).unwrap();
    assert!(!rows.is_empty(), "the inclusion traps no air");
    let area: f64 = rows.iter().map(|r| r[col("area")]).sum();
    let centre = [0, 1].map(|d| {
        let c = col(["x", "y"][d]);
        rows.iter().map(|r| r[c] * r[col("area")]).sum::<f64>() / area
    });
    // What the cure removed: the underfill particles the fill left empty.
    let empty: Vec<usize> = (0..liquid.len())
        .filter(|&p| material[p] == UNDERFILL && liquid[p] < 0.5)
        .collect();
    assert_eq!(cure["removed_particles"], json!(empty.len()));
    assert_eq!(
        cure["particles"],
        json!(liquid.len() - empty.len()),
        "{cure}"
    );
    let cell = s["domain"]["cell_size"].as_f64().unwrap();
    let particle_area = cell * cell / 4.0;
    let removed_area = empty.len() as f64 * particle_area;
    // The empty space is the trapped air to within one cell (the front's cells are part
    // full: a cell counts as empty below half).
    assert!(
        (removed_area - area).abs() <= cell * cell,
        "removed {removed_area:e} m² for {area:e} m² of trapped air"
    );
    let removed_centre =
        [0, 1].map(|d| empty.iter().map(|&p| x[2 * p + d]).sum::<f64>() / empty.len() as f64);
    for d in 0..2 {
        assert!(
            (removed_centre[d] - centre[d]).abs() <= 1.5 * cell,
            "removed particles centred at {removed_centre:?}, voids at {centre:?}"
        );
    }
    // The rest carries on where it was, with its temperature and cure: the cure stage's
    // first frame is the fill's last without the removed particles, in the same order.
    let kept: Vec<usize> = (0..liquid.len())
        .filter(|p| empty.binary_search(p).is_err())
        .collect();
    for (name, width) in [("x", 2), ("temperature", 1), ("cure", 1)] {
        let (before, after) = (field(&fill_store, name, last), field(&cure_store, name, 0));
        let carried: Vec<f64> = kept
            .iter()
            .flat_map(|&p| before[width * p..width * (p + 1)].iter().copied())
            .collect();
        assert_eq!(carried, after, "{name} was not carried over");
    }
    // And the cure goes on from there: the oven warms the underfill and it starts to cure.
    let (cure0, cure1) = (field(&cure_store, "cure", 0), field(&cure_store, "cure", 2));
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(
        mean(&cure1) > mean(&cure0),
        "{} {}",
        mean(&cure0),
        mean(&cure1)
    );
}

#[test]
fn a_bump_free_fill_in_the_package_follows_the_plate_law() {
    // The fill stage without the inclusion and the bump, die and substrate bounding the
    // gap: the front
    // against x² = hσcosθ t/(3μ), measured over the underfill's particles only. Measured:
    // front error 0.024, fill time −8.6% (5 cells across the gap); at 10 cells 0.013 and
    // −4.2% (README).
    let dir = tempfile::tempdir().unwrap();
    let mut s = process_scene();
    let stages = s["stages"].as_array().unwrap()[..1].to_vec();
    s["stages"] = Value::Array(stages);
    let bodies: Vec<Value> = s["bodies"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|b| b["name"] != "inclusion" && b["name"] != "bump")
        .cloned()
        .collect();
    s["bodies"] = Value::Array(bodies);
    s["physics"]["underfill"]
        .as_object_mut()
        .unwrap()
        .remove("vent_regions");
    s["bodies"][1].as_object_mut().unwrap().remove("holes");
    s["reference"] = json!({
        "type": "capillary_filling", "axis": 0, "entrance": 1e-3, "length": 1e-3, "gap": 5e-5,
        "surface_tension": 0.03, "contact_angle": 30.0, "viscosity": 0.3,
        "materials": ["underfill"]
    });
    let metrics = run_scene_json(dir.path(), "plain", &s);
    let error = metrics["error"].as_f64().unwrap();
    assert!(error < 0.03, "front error {error}");
    let fill_time = metrics["comparisons"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["quantity"] == "fill_time")
        .unwrap()["relative_difference"]
        .as_f64()
        .unwrap();
    assert!(fill_time.abs() < 0.10, "fill time off by {fill_time}");
}

/// The whole chain: the cured underfill cracks during the first thermal cycle and the crack
/// grows every cycle, and each stage's `damage` summary agrees with its store. The section
/// has two stress raisers, the void the fill trapped and the corner where the bump meets
/// the die; the first failure is at one of them, and both have cracked by the end of the
/// second cycle. Which one fails first is close. Measured with the mechanical stages on
/// the linear kernel with F-bar (stop 79): at the bump corner at 3,900 s (x = 43 µm,
/// y = 148 µm; 3,840 s at 41, 149 µm with 5 µm cells), 359 / 437 / 559 failed particles
/// after the cycles. On the linear kernel without F-bar: by the second void at 4,140 s
/// (x = 408 µm, y = 103 µm, 23 µm from its centre), 346 / 421 / 580. With quadratic
/// B-splines (before): by the first void at 5,580 s (x = 497 µm, y = 147 µm),
/// 227 / 327 / 504; with the cure's predictor alone (0.02 more cure at the end of the
/// oven) at the bump corner at 4,740 s, 298 / 497 / 645; with σzz left out, by the void
/// at 3,900 s, 37 / 62 / 85.
#[test]
fn the_chain_cracks_in_the_first_cycle_at_the_bump_and_by_its_void() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = process_scene();
    // The last cycle also stores the joint's work and the particles' mass (the layer
    // figures are checked against them below).
    let mut fields = scene["stages"][1]["changes"]["output"]["fields"].clone();
    for extra in ["inelastic_work", "mass"] {
        fields.as_array_mut().unwrap().push(json!(extra));
    }
    scene["stages"][5]["changes"]["output"]["fields"] = fields;
    let metrics = run_scene_json(dir.path(), "chain", &scene);
    let stages = metrics["stages"].as_array().unwrap();
    let failed = |name: &str| {
        let s = stages.iter().find(|s| s["name"] == name).unwrap();
        assert_eq!(s["outcome"], "finished", "{name}");
        s["damage"]["underfill"]["failed_particles"]
            .as_u64()
            .unwrap()
    };
    assert_eq!(failed("cool"), 0, "cracked before the cycles");
    let per_cycle = ["cycle-1", "cycle-2", "cycle-3"].map(failed);
    assert!(
        per_cycle[0] > 0 && per_cycle[1] > per_cycle[0] && per_cycle[2] > per_cycle[1],
        "failed particles per cycle {per_cycle:?}"
    );
    let root = dir.path().join("chain/underfill-process-2d.zarr");
    let store = ResultStore::open(&root).unwrap().stage("cycle-1").unwrap();
    let (columns, rows) = ResultStore::open(&root)
        .unwrap()
        .stage("fill")
        .unwrap()
        .table("underfill_voids")
        .unwrap()
        .unwrap();
    let col = |name: &str| columns.iter().position(|c| c == name).unwrap();
    let void = [rows[0][col("x")], rows[0][col("y")]];
    let (first_frame, first) = (0..store.frame_count().unwrap())
        .find_map(|frame| {
            let damage = store.frame("damage", frame).unwrap().1;
            let x = store.frame("x", frame).unwrap().1;
            let failed: Vec<(usize, [f64; 2])> = (0..damage.len())
                .filter(|&p| damage[p] >= 1.0)
                .map(|p| (p, [x[2 * p], x[2 * p + 1]]))
                .collect();
            (!failed.is_empty()).then_some((frame as usize, failed))
        })
        .expect("no particle failed in the first cycle");
    // The summary's onset is the step the first of them failed in: between the frame
    // before and the frame that shows it, one of them, by the void (within 30 µm of its
    // centre along the gap and 10 µm across it) or within two cells (20 µm) of the corner
    // where the bump (x ≤ 40 µm) meets the die (y = 150 µm).
    let figures = |name: &str| {
        stages.iter().find(|s| s["name"] == name).unwrap()["damage"]["underfill"].clone()
    };
    for quiet in ["cure", "cool"] {
        assert!(figures(quiet)["onset"].is_null(), "{quiet} has an onset");
    }
    let onset = &figures("cycle-1")["onset"];
    let times = store.times().unwrap();
    let time = onset["time"].as_f64().unwrap();
    assert!(
        time > times[first_frame - 1] && time <= times[first_frame] * (1.0 + 1e-12),
        "onset at {time} s, first seen at {} s",
        times[first_frame]
    );
    let particle = onset["particle"].as_u64().unwrap() as usize;
    assert!(
        first.iter().any(|(p, _)| *p == particle),
        "onset particle {particle}"
    );
    let at = [
        onset["position"][0].as_f64().unwrap(),
        onset["position"][1].as_f64().unwrap(),
    ];
    let corner = [40e-6, 150e-6];
    let at_corner =
        |p: [f64; 2]| ((p[0] - corner[0]).powi(2) + (p[1] - corner[1]).powi(2)).sqrt() < 20e-6;
    let at_void = |p: [f64; 2]| (p[0] - void[0]).abs() < 30e-6 && (p[1] - void[1]).abs() < 10e-6;
    assert!(
        at_corner(at) || at_void(at),
        "onset at {at:?}: neither the bump's corner at {corner:?} nor the void at {void:?}"
    );
    // The cracks grow from cycle to cycle.
    let length = |name: &str| figures(name)["crack_length"].as_f64().unwrap();
    assert!(figures("cycle-1")["cracks"].as_u64().unwrap() >= 1);
    assert!(
        length("cycle-1") > 0.0 && length("cycle-3") >= length("cycle-1"),
        "crack lengths {} → {} m",
        length("cycle-1"),
        length("cycle-3")
    );
    // The summary counts what the store holds at the stage's end.
    let last = store
        .frame("damage", store.frame_count().unwrap() - 1)
        .unwrap()
        .1;
    let in_store = last.iter().filter(|&&d| d >= 1.0).count() as u64;
    assert_eq!(in_store, per_cycle[0]);
    // By the end of the first cycle the crack has reached the void: failed particles
    // within 30 µm of its centre along the gap and 10 µm across it.
    let x_end = store
        .frame("x", store.frame_count().unwrap() - 1)
        .unwrap()
        .1;
    let by_void = (0..last.len())
        .filter(|&p| {
            last[p] >= 1.0
                && (x_end[2 * p] - void[0]).abs() < 30e-6
                && (x_end[2 * p + 1] - void[1]).abs() < 10e-6
        })
        .count();
    assert!(by_void > 0, "no failed particle by the void at {void:?}");
    // ... and by the end of the second the bump's corner has cracked too.
    let second = ResultStore::open(&root).unwrap().stage("cycle-2").unwrap();
    let end = second.frame_count().unwrap() - 1;
    let (damage, x) = (
        second.frame("damage", end).unwrap().1,
        second.frame("x", end).unwrap().1,
    );
    let by_corner = (0..damage.len())
        .filter(|&p| damage[p] >= 1.0 && at_corner([x[2 * p], x[2 * p + 1]]))
        .count();
    assert!(
        by_corner > 0,
        "no failed particle by the bump's corner after cycle 2"
    );
    // The first cycle's damaged sites (damage ≥ 0.5, most damaged first) show the
    // rival of the site that failed first: one lies by the bump's side (its centre within
    // 30 µm of x = 40 µm), measured 0.70 at the bump's substrate corner and 0.69 at its
    // die corner, among 8 sites of which 3 have failed.
    let sites = figures("cycle-1")["sites"].as_array().unwrap().clone();
    let peak = |s: &serde_json::Value| s["peak"].as_f64().unwrap();
    assert!(
        !sites.is_empty() && sites.len() <= 6,
        "{} sites",
        sites.len()
    );
    assert!(sites.windows(2).all(|w| peak(&w[0]) >= peak(&w[1])));
    assert_eq!(peak(&sites[0]), 1.0);
    assert!(
        sites
            .iter()
            .any(|s| peak(s) >= 0.5 && (s["centre"][0].as_f64().unwrap() - 40e-6).abs() < 30e-6),
        "no damaged site by the bump after cycle 1: {sites:?}"
    );
    // The solder bump's inelastic work grows every stage; the cycles settle (a stable
    // hysteresis loop: cycles 2 and 3 within 5%; measured 0.1897 and 0.1886 MJ/m³), and
    // the life each gives is the scene's fatigue law at that work.
    let law = &process_scene()["materials"]["solder"]["fatigue"];
    let (c, k) = (
        law["coefficient"].as_f64().unwrap(),
        law["exponent"].as_f64().unwrap(),
    );
    let growth = &law["growth"];
    let (growth_k, growth_m, crack_length) = (
        growth["coefficient"].as_f64().unwrap(),
        growth["exponent"].as_f64().unwrap(),
        growth["crack_length"].as_f64().unwrap(),
    );
    let solder = |name: &str| {
        stages.iter().find(|s| s["name"] == name).unwrap()["fatigue"]["solder"].clone()
    };
    let mut before = 0.0;
    for name in ["cure", "cool", "cycle-1", "cycle-2", "cycle-3"] {
        let f = solder(name);
        let (work, in_stage) = (
            f["work"].as_f64().unwrap(),
            f["work_in_stage"].as_f64().unwrap(),
        );
        assert!(in_stage > 0.0 && work > before, "{name}: {f}");
        assert!(
            (work - before - in_stage).abs() <= 1e-9 * work,
            "{name}: {f}"
        );
        let cycles = f["cycles_to_crack"].as_f64().unwrap();
        let expected = c * in_stage.powf(k);
        assert!((cycles - expected).abs() <= 1e-12 * expected, "{name}: {f}");
        // Darveaux's growth: then the crack crosses the joint at da/dN = K ΔW^m.
        let failure = f["cycles_to_failure"].as_f64().unwrap();
        let expected = expected + crack_length / (growth_k * in_stage.powf(growth_m));
        assert!(
            (failure - expected).abs() <= 1e-12 * expected,
            "{name}: {f}"
        );
        before = work;
    }
    let per_cycle = ["cycle-2", "cycle-3"].map(|n| solder(n)["work_in_stage"].as_f64().unwrap());
    assert!(
        (per_cycle[1] - per_cycle[0]).abs() < 0.05 * per_cycle[0],
        "work per cycle {per_cycle:?}"
    );
    // Darveaux's layers (`output.fatigue_layer`, 10 µm at the die and at the substrate):
    // each layer's work is the mass-weighted (one density: reference-volume-weighted) mean
    // of the stored work over the joint's particles within 10 µm of a particle of that
    // material at the stage's end; its increase over the stage gives its life.
    let layer = &process_scene()["output"]["fatigue_layer"];
    let thickness = layer["thickness"].as_f64().unwrap();
    let cycle = ResultStore::open(&root).unwrap().stage("cycle-3").unwrap();
    let last_frame = cycle.frame_count().unwrap() - 1;
    let read = |name: &str| cycle.frame(name, last_frame).unwrap().1;
    let (x, work, mass, material) = (
        read("x"),
        read("inelastic_work"),
        read("mass"),
        read("material"),
    );
    // Materials in name order: silicon, solder, substrate, underfill.
    let index = |name: &str| {
        ["silicon", "solder", "substrate", "underfill"]
            .iter()
            .position(|m| *m == name)
            .unwrap() as f64
    };
    let at = |p: usize| [x[2 * p], x[2 * p + 1]];
    let joint: Vec<usize> = (0..mass.len())
        .filter(|&p| material[p] == index("solder"))
        .collect();
    for along in ["silicon", "substrate"] {
        let pads: Vec<[f64; 2]> = (0..mass.len())
            .filter(|&p| material[p] == index(along))
            .map(at)
            .collect();
        let (mut weighted, mut total) = (0.0, 0.0);
        for &p in &joint {
            let [px, py] = at(p);
            if pads
                .iter()
                .any(|q| ((q[0] - px).powi(2) + (q[1] - py).powi(2)).sqrt() <= thickness)
            {
                weighted += work[p] * mass[p];
                total += mass[p];
            }
        }
        let figures = &solder("cycle-3")["layers"][along];
        let reported = figures["work"].as_f64().unwrap();
        println!("layer by {along}: {figures}");
        assert!(
            total > 0.0,
            "no joint particle within {thickness} m of {along}"
        );
        assert!(
            (reported - weighted / total).abs() <= 1e-9 * reported,
            "{along}: reported {reported}, stored {}",
            weighted / total
        );
        let before = solder("cycle-2")["layers"][along]["work"].as_f64().unwrap();
        let in_stage = figures["work_in_stage"].as_f64().unwrap();
        assert!((reported - before - in_stage).abs() <= 1e-9 * reported);
        let cycles = figures["cycles_to_crack"].as_f64().unwrap();
        assert!((cycles - c * in_stage.powf(k)).abs() <= 1e-12 * cycles);
    }
}
