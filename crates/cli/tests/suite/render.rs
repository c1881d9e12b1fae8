//! `mpm render` end to end: a short 2D run drawn as a PNG (with and without a voids table
//! in the store's metrics), and the errors for a missing field, a frame out of range, an
//! unwritable output, the views of a 3D store, and the outlines of a refined run's levels.

use crate::common;

use common::*;
use std::path::Path;

/// Runs an example with `--set` overrides into `dir/out`; returns the store's path.
fn run_example(dir: &Path, name: &str, overrides: &[&str]) -> String {
    let scene = example(&format!("{name}.json"));
    let mut args = vec!["run", scene.to_str().unwrap(), "--out", "out", "--quiet"];
    for o in overrides {
        args.extend(["--set", o]);
    }
    let o = mpm(&args, dir);
    assert_eq!(o.status.code(), Some(0), "mpm run {name}: {}", text(&o));
    format!("out/{name}.zarr")
}

/// Width and height from the IHDR chunk of a PNG file.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert!(
        bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
        "{} is not a PNG",
        path.display()
    );
    assert_eq!(&bytes[12..16], b"IHDR");
    let word = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
    (word(16), word(20))
}

/// Heat slab to t = 0.2 s with two output frames (three stored, t = 0 included).
const SLAB: [&str; 2] = ["solver.end_time=0.2", "output.frames=2"];

#[test]
fn render_draws_a_2d_store_as_png() {
    let dir = tempfile::tempdir().unwrap();
    let store = run_example(dir.path(), "heat-slab", &SLAB);

    let o = mpm(
        &["render", &store, "--field", "temperature", "--out", "t.png"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(
        text(&o).contains("frame 2"),
        "last frame by default: {}",
        text(&o)
    );
    let (w, h) = png_size(&dir.path().join("t.png"));
    // 10 mm x 2 mm: 1000 px by 200 px of plot, plus title, axes and colour bar.
    assert!(w > 1000 && h > 200 && w > h, "{w} x {h}");

    // First frame from the end, a component of a vector field, a title.
    let o = mpm(
        &[
            "render",
            &store,
            "--field",
            "x",
            "--component",
            "1",
            "--frame",
            "-3",
            "--title",
            "slab",
            "--out",
            "x.png",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("frame 0"), "{}", text(&o));
    assert!(png_size(&dir.path().join("x.png")).0 > 200);
}

#[test]
fn render_marks_the_voids_of_a_metrics_table() {
    let dir = tempfile::tempdir().unwrap();
    let store = run_example(dir.path(), "heat-slab", &SLAB);

    // No table yet: a warning, and the picture without voids.
    let o = mpm(
        &[
            "render",
            &store,
            "--field",
            "temperature",
            "--voids",
            "voids",
            "--out",
            "a.png",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("warning: no table `voids`"),
        "{}",
        text(&o)
    );
    assert!(!text(&o).contains("voids marked"), "{}", text(&o));

    // Add a table of voids to the store's metrics attribute.
    let meta = dir.path().join(&store).join("zarr.json");
    let mut root: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&meta).unwrap()).unwrap();
    root["attributes"]["metrics"]["tables"] = serde_json::json!({ "voids": {
        "columns": ["id", "x", "y", "area"],
        "rows": [[1, 0.003, 0.001, 3.1e-8], [2, 0.007, 0.0005, 1e-7]]
    } });
    std::fs::write(&meta, serde_json::to_string(&root).unwrap()).unwrap();
    let o = mpm(
        &[
            "render",
            &store,
            "--field",
            "temperature",
            "--voids",
            "voids",
            "--out",
            "b.png",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("2 voids marked"), "{}", text(&o));
    assert!(png_size(&dir.path().join("b.png")).0 > 200);
    assert_ne!(
        std::fs::read(dir.path().join("a.png")).unwrap(),
        std::fs::read(dir.path().join("b.png")).unwrap(),
        "the voids are drawn"
    );
}

#[test]
fn render_refuses_missing_fields_frames_outputs_and_3d_stores() {
    let dir = tempfile::tempdir().unwrap();
    let store = run_example(dir.path(), "heat-slab", &SLAB);
    let refused = |args: &[&str], expected: &[&str]| {
        let mut all = vec!["render", store.as_str()];
        all.extend(args);
        let o = mpm(&all, dir.path());
        let t = text(&o);
        assert_ne!(o.status.code(), Some(0), "{args:?}: {t}");
        for e in expected {
            assert!(t.contains(e), "{args:?}: expected `{e}` in: {t}");
        }
    };
    refused(
        &["--field", "nope", "--out", "n.png"],
        &["`nope`", "available fields: temperature, x"],
    );
    refused(
        &["--field", "temperature", "--frame", "3", "--out", "n.png"],
        &["frame 3 is out of range", "3 frame(s)"],
    );
    refused(
        &["--field", "temperature", "--frame", "-4", "--out", "n.png"],
        &["out of range"],
    );
    refused(
        &["--field", "x", "--component", "2", "--out", "n.png"],
        &["2 component(s)"],
    );
    refused(
        &["--field", "temperature", "--out", "no-such-dir/n.png"],
        &["cannot write `no-such-dir/n.png`"],
    );
    assert!(!dir.path().join("n.png").exists());

    refused(
        &["--field", "temperature", "--slab", "0:1", "--out", "n.png"],
        &["a 2D store has no depth"],
    );
    refused(
        &["--field", "temperature", "--plane", "xz", "--out", "n.png"],
        &["only the xy plane"],
    );
    assert!(!dir.path().join("n.png").exists());
}

#[test]
fn render_draws_a_3d_store_seen_along_an_axis_whole_or_a_slab() {
    let dir = tempfile::tempdir().unwrap();
    // The cube drop, shrunk to 8 x 8 x 8 particles and two steps.
    let cube = run_example(
        dir.path(),
        "cube-drop",
        &[
            "solver.end_time=0.0002",
            "output.frames=1",
            "domain.cell_size=0.0625",
            "bodies[0].shape.box.max=[0.55,0.55,0.55]",
        ],
    );
    let drawn = |args: &[&str]| -> (String, usize) {
        let mut all = vec!["render", cube.as_str(), "--field", "v", "--component", "1"];
        all.extend(args);
        let o = mpm(&all, dir.path());
        let t = text(&o);
        assert_eq!(o.status.code(), Some(0), "{args:?}: {t}");
        // "wrote c.png (frame 1, t = ... s, N particles, ...)"
        let n = t
            .split(" particles")
            .next()
            .and_then(|head| head.rsplit(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no particle count in: {t}"));
        (t, n)
    };
    let (_, all) = drawn(&["--out", "c.png"]);
    assert!(all > 100, "{all}");
    assert!(png_size(&dir.path().join("c.png")).0 > 200);
    let (_, side) = drawn(&["--plane", "xz", "--out", "side.png"]);
    assert_eq!(side, all);
    assert_ne!(
        std::fs::read(dir.path().join("c.png")).unwrap(),
        std::fs::read(dir.path().join("side.png")).unwrap(),
        "another plane is another picture"
    );
    // A slab of two of the cube's eight particle layers.
    let (t, slab) = drawn(&["--plane", "xz", "--slab", "0.4:0.45", "--out", "slab.png"]);
    assert!(slab > 0 && 3 * slab < all, "{slab} of {all}: {t}");
    let o = mpm(
        &[
            "render", &cube, "--field", "v", "--slab", "0.3:0.2", "--out", "bad.png",
        ],
        dir.path(),
    );
    assert_ne!(o.status.code(), Some(0));
    assert!(text(&o).contains("LO:HI"), "{}", text(&o));
    assert!(!dir.path().join("bad.png").exists());
}

#[test]
fn render_deformed_draws_a_stretched_body_whole() {
    // The stretched bar in total Lagrangian MPM is whole at 2.8 times its length; drawn as
    // upright squares of its particles' spacing it shows as slices, drawn deformed by F it
    // fills its outline.
    let dir = tempfile::tempdir().unwrap();
    let store = run_example(dir.path(), "stretched-bar", &[]);
    let coloured = |png: &str, extra: &[&str]| {
        let mut args = vec!["render", &store, "--field", "J", "--out", png];
        args.extend_from_slice(extra);
        let o = mpm(&args, dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", text(&o));
        let (width, height, pixels) = decode_png(&dir.path().join(png));
        // Viridis colours (not the white page or the black text) above the axis labels
        // and the colour bar, the lowest 150 px.
        let plot = (width * height.saturating_sub(150)) as usize;
        pixels[..plot]
            .iter()
            .filter(|p| p[0] < 200 && (p[1] > 40 || p[2] > 40))
            .count()
    };
    let upright = coloured("upright.png", &[]);
    let deformed = coloured("deformed.png", &["--deformed"]);
    // Measured: 4,000 and 10,883 pixels.
    println!("coloured pixels: upright {upright}, deformed {deformed}");
    assert!(
        deformed as f64 > 2.0 * upright as f64,
        "upright {upright}, deformed {deformed}"
    );
    // A store without F is refused, naming the field.
    let bar = run_example(dir.path(), "vibrating-bar", &["solver.end_time=0.01"]);
    let o = mpm(
        &[
            "render",
            &bar,
            "--field",
            "v",
            "--deformed",
            "--out",
            "b.png",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("\"F\""), "{}", text(&o));
}

#[test]
fn render_outlines_the_refined_levels_of_a_refined_run() {
    // The vibrating bar with one level over x = 0.5–1.2: its region grows to the base
    // elements it touches (x = 0.475–1.225) and reaches past the bar above and below, so
    // the picture shows two vertical lines across the bar; `--no-levels` leaves them out.
    let dir = tempfile::tempdir().unwrap();
    let store = run_example(
        dir.path(),
        "vibrating-bar",
        &[
            "solver.end_time=0.01",
            r#"solver.refinement={"levels":[{"boxes":[{"min":[0.5,-0.1],"max":[1.2,0.3]}]}]}"#,
        ],
    );
    let o = mpm(
        &["render", &store, "--field", "v", "--out", "levels.png"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(
        text(&o).contains("1 refined level(s) outlined"),
        "{}",
        text(&o)
    );
    let o = mpm(
        &[
            "render",
            &store,
            "--field",
            "v",
            "--no-levels",
            "--out",
            "plain.png",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(!text(&o).contains("outlined"), "{}", text(&o));
    let (width, height, with) = decode_png(&dir.path().join("levels.png"));
    let (w2, h2, without) = decode_png(&dir.path().join("plain.png"));
    assert_eq!((width, height), (w2, h2));
    // Columns where the pictures differ, below the title (whose text differs) and above
    // the axis labels and colour bar (the lowest 150 px).
    let mut columns: Vec<u32> = (70..height.saturating_sub(150))
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let k = (y * width + x) as usize;
            with[k] != without[k]
        })
        .map(|(x, _)| x)
        .collect();
    columns.sort_unstable();
    columns.dedup();
    let mut groups: Vec<(u32, u32)> = Vec::new();
    for c in columns {
        match groups.last_mut() {
            // A white line on the white page beyond the bar differs by its black edges only.
            Some(g) if c <= g.1 + 4 => g.1 = c,
            _ => groups.push((c, c)),
        }
    }
    assert_eq!(groups.len(), 2, "columns that differ: {groups:?}");
    assert!(groups.iter().all(|g| g.1 - g.0 <= 6), "{groups:?}");
    // 0.75 m apart on a 1.5 m wide picture drawn 1000 px wide: about 500 px.
    let apart = groups[1].0 as f64 - groups[0].0 as f64;
    assert!((apart - 500.0).abs() < 30.0, "{groups:?}");
}

#[test]
fn render_marks_the_voids_of_the_stage_it_draws() {
    // A staged run keeps each stage's tables in its stage's metrics: the pit's fill stage
    // (ended at its fill time by `solver.end_when`) holds the void it closed, which
    // `--stage fill --voids underfill_voids` marks; the run's own metrics have no tables.
    let dir = tempfile::tempdir().unwrap();
    let store = run_example(
        dir.path(),
        "liquid-void-pit",
        &[PIT_FILL_REGION, PIT_STAGES_FILL_THEN_REST],
    );
    let o = mpm(
        &[
            "render",
            &store,
            "--stage",
            "fill",
            "--field",
            "v",
            "--voids",
            "underfill_voids",
            "--out",
            "fill.png",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("1 void marked"), "{}", text(&o));
}
