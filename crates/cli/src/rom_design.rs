//! `mpm rom design`: the parametric training set of a reduced model, as the paper draws it.
//! Training and held-out parameters come from two Latin hypercubes over the ranges given
//! (each range cut into as many strata as points, one point per stratum in every parameter,
//! the strata paired at random), written as scenes and a table, and run on request.

use crate::exit_status::ExitStatus;
use crate::overrides::{apply_override, value_at};
use crate::progress::ProgressReporter;
use crate::scene_file::report_load_error;
use crate::stdout::outln;
use anyhow::Context;
use mpm_core::output::Outcome;
use mpm_core::plugin::Registry;
use mpm_core::scene::parse_scene_value;
use std::path::{Path, PathBuf};

/// Settings of `mpm rom design`.
#[derive(Debug, clap::Args)]
pub struct DesignArgs {
    /// Scene file: the scene the model is for.
    scene: PathBuf,
    /// A parameter and its range, `PATH=LO:HI`, PATH a number of the scene as `--set` names
    /// it (`obstacles[0].velocity[0]=0:0.2`); repeatable, one hypercube dimension each.
    #[arg(long = "vary", value_name = "PATH=LO:HI", required = true)]
    vary: Vec<String>,
    /// Training points.
    #[arg(long, default_value_t = 8)]
    train: usize,
    /// Held-out points (their own hypercube).
    #[arg(long, default_value_t = 2)]
    test: usize,
    /// Seed of the strata's pairing and of the points within them.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Change a scene value first, for every point (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    set: Vec<String>,
    /// Output folder (default results/<scene>-rom-design): `train/` and `test/` with a scene
    /// per point (and its store with --run), `design.csv` and `design.json`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also run every point's scene into its folder (training runs first).
    #[arg(long)]
    run: bool,
    /// No progress output.
    #[arg(long, short)]
    quiet: bool,
}

/// One varied parameter.
struct Range {
    path: String,
    low: f64,
    high: f64,
}

/// SplitMix64: a small, seeded generator, so a design is the same on every machine.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in 0..n.
    fn below(&mut self, n: usize) -> usize {
        (self.unit() * n as f64) as usize % n.max(1)
    }
}

/// A Latin hypercube of `n` points in the unit cube of `dims` dimensions: in every
/// dimension each of the `n` strata holds one point, at a uniform place within it.
pub fn latin_hypercube(n: usize, dims: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = SplitMix(seed);
    let mut points = vec![vec![0.0; dims]; n];
    for d in 0..dims {
        let mut strata: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            strata.swap(i, rng.below(i + 1));
        }
        for (point, stratum) in points.iter_mut().zip(strata) {
            point[d] = (stratum as f64 + rng.unit()) / n as f64;
        }
    }
    points
}

fn parse_range(text: &str, scene: &serde_json::Value) -> Result<Range, String> {
    let (path, range) = text
        .split_once('=')
        .ok_or_else(|| format!("--vary `{text}`: expected PATH=LO:HI"))?;
    let (low, high) = range
        .split_once(':')
        .and_then(|(a, b)| Some((a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?)))
        .ok_or_else(|| format!("--vary `{text}`: the range must be two numbers LO:HI"))?;
    if !(low.is_finite() && high.is_finite() && low < high) {
        return Err(format!("--vary `{text}`: LO must be below HI"));
    }
    match value_at(scene, path) {
        Ok(Some(v)) if v.is_number() => Ok(Range {
            path: path.to_string(),
            low,
            high,
        }),
        Ok(Some(v)) => Err(format!(
            "--vary `{path}`: the scene holds {v} there, not a number"
        )),
        Ok(None) => Err(format!("--vary `{path}`: the scene has no value there")),
        Err(e) => Err(format!("--vary: {e:#}")),
    }
}

/// Runs `mpm rom design`.
pub fn design(args: &DesignArgs, registry: &Registry) -> anyhow::Result<ExitStatus> {
    let text = std::fs::read_to_string(&args.scene)
        .with_context(|| format!("cannot read scene file `{}`", args.scene.display()))?;
    let mut base: serde_json::Value = match serde_json::from_str(&text) {
        Ok(v) => v,
        Err(e) => {
            eprintln!("error: {}: $: not valid JSON: {e}", args.scene.display());
            return Ok(ExitStatus::InvalidInput);
        }
    };
    for o in &args.set {
        if let Err(e) = apply_override(&mut base, o) {
            eprintln!("error: {}: --set: {e:#}", args.scene.display());
            return Ok(ExitStatus::InvalidInput);
        }
    }
    let ranges: Vec<Range> = match args.vary.iter().map(|v| parse_range(v, &base)).collect() {
        Ok(r) => r,
        Err(message) => {
            eprintln!("error: {}: {message}", args.scene.display());
            return Ok(ExitStatus::InvalidInput);
        }
    };
    if args.train < 2 || args.test < 1 {
        eprintln!("error: --train must be at least 2 and --test at least 1");
        return Ok(ExitStatus::InvalidInput);
    }
    let name = base["name"].as_str().unwrap_or("scene").to_string();
    let stem = args
        .scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results").join(format!("{stem}-rom-design")));
    let scene_dir = args.scene.parent().unwrap_or(Path::new("."));
    // Every point's scene, validated before anything is written or run.
    let mut points = Vec::new();
    for (set, count, seed) in [
        ("train", args.train, args.seed),
        ("test", args.test, !args.seed),
    ] {
        for (k, unit) in latin_hypercube(count, ranges.len(), seed)
            .iter()
            .enumerate()
        {
            let mut scene = base.clone();
            let point_name = format!("{name}-{set}-{k}");
            scene["name"] = serde_json::json!(point_name);
            let values: Vec<f64> = ranges
                .iter()
                .zip(unit)
                .map(|(r, u)| r.low + u * (r.high - r.low))
                .collect();
            for (r, v) in ranges.iter().zip(&values) {
                apply_override(&mut scene, &format!("{}={v}", r.path))?;
            }
            let validated = match parse_scene_value(scene.clone(), registry, scene_dir) {
                Ok(v) => v,
                Err(e) => {
                    return Ok(report_load_error(
                        &args.scene,
                        crate::scene_file::LoadError::Invalid(e),
                    ));
                }
            };
            points.push((set, point_name, values, scene, validated));
        }
    }
    let mut csv = String::from("set,name");
    for r in &ranges {
        csv.push_str(&format!(",{}", r.path.replace(',', ";")));
    }
    csv.push('\n');
    let mut table = Vec::new();
    for (set, point_name, values, scene, _) in &points {
        let folder = dir.join(set);
        std::fs::create_dir_all(&folder)
            .with_context(|| format!("creating {}", folder.display()))?;
        let file = folder.join(format!("{point_name}.json"));
        std::fs::write(&file, serde_json::to_string_pretty(scene)?)
            .with_context(|| format!("writing {}", file.display()))?;
        csv.push_str(&format!("{set},{point_name}"));
        for v in values {
            csv.push_str(&format!(",{v}"));
        }
        csv.push('\n');
        table.push(serde_json::json!({"set": set, "name": point_name, "values": values}));
    }
    std::fs::write(dir.join("design.csv"), csv)?;
    let json = serde_json::json!({
        "scene": args.scene,
        "seed": args.seed,
        "parameters": ranges.iter().map(|r| serde_json::json!({
            "path": r.path, "low": r.low, "high": r.high,
        })).collect::<Vec<_>>(),
        "points": table,
    });
    std::fs::write(
        dir.join("design.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    outln!(
        "wrote {} training and {} held-out scenes to {} (design.csv, design.json)",
        args.train,
        args.test,
        dir.display()
    )?;
    if !args.run {
        return Ok(ExitStatus::Success);
    }
    let mut status = ExitStatus::Success;
    for (set, point_name, _, _, validated) in &points {
        let store = dir.join(set).join(format!("{point_name}.zarr"));
        let mut progress = ProgressReporter::new(args.quiet);
        let result = mpm_core::solver::run_scene(
            validated,
            &mut mpm_io::ZarrSink::new(&store),
            &mut progress,
        );
        progress.finish();
        let metrics = result.with_context(|| format!("running {point_name}"))?;
        let finished = metrics.outcome == Some(Outcome::Finished);
        if !finished {
            status = ExitStatus::Stopped;
        }
        outln!(
            "{set} {point_name}: {:?}, {} steps, {:.2} s -> {}",
            metrics.outcome.unwrap_or(Outcome::Finished),
            metrics.steps,
            metrics.wall_seconds,
            store.display()
        )?;
    }
    Ok(status)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_stratum_of_each_dimension_holds_one_point() {
        for (n, dims) in [(8, 2), (2, 3), (13, 1)] {
            let points = latin_hypercube(n, dims, 7);
            assert_eq!(points.len(), n);
            for d in 0..dims {
                let mut strata: Vec<usize> =
                    points.iter().map(|p| (p[d] * n as f64) as usize).collect();
                strata.sort_unstable();
                assert_eq!(strata, (0..n).collect::<Vec<_>>(), "n {n}, dimension {d}");
            }
        }
        assert_eq!(latin_hypercube(8, 2, 7), latin_hypercube(8, 2, 7));
        assert_ne!(latin_hypercube(8, 2, 7), latin_hypercube(8, 2, 8));
    }
}
