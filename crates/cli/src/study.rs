//! `mpm study`: run a scene over a sweep of settings and put error against run time.

use crate::exit_status::{ExitStatus, input_error};
use crate::scene_file::{LoadError, load_scene};
use anyhow::Context;
use mpm_core::output::Outcome;
use mpm_core::plugin::Registry;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One swept setting: a scene path (or alias) and its values.
#[derive(Clone, Debug)]
pub struct Variation {
    /// The name given on the command line (`cell_size`, `solver.cfl`, ...).
    pub key: String,
    /// The scene paths it sets (an alias may set several).
    pub paths: Vec<String>,
    /// Values, as written on the command line (read as JSON, else as strings).
    pub values: Vec<String>,
}

/// Short names for the usual axes of a study.
fn alias(key: &str, bodies: usize) -> Vec<String> {
    let one = |p: &str| vec![p.to_string()];
    match key {
        "cell_size" => one("domain.cell_size"),
        "kernel" => one("solver.kernel"),
        "transfer" => one("solver.transfer"),
        "scheme" => one("solver.scheme"),
        "cfl" => one("solver.cfl"),
        "mls" => one("solver.mls"),
        "dt" => one("solver.dt"),
        "mechanics" => one("solver.mechanics"),
        "ppc" => (0..bodies)
            .map(|i| format!("bodies[{i}].particles_per_cell"))
            .collect(),
        other => one(other),
    }
}

/// Parses `KEY=V1,V2,...` for a scene with `bodies` bodies.
pub fn parse_variation(text: &str, bodies: usize) -> anyhow::Result<Variation> {
    let (key, values) = text
        .split_once('=')
        .ok_or_else(|| input_error!("--vary `{text}`: expected KEY=VALUE1,VALUE2,..."))?;
    let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
    if key.is_empty() || values.iter().any(String::is_empty) {
        return Err(input_error!("--vary `{text}`: empty key or value"));
    }
    Ok(Variation {
        key: key.to_string(),
        paths: alias(key, bodies),
        values,
    })
}

/// One run of a study.
#[derive(Clone, Debug, Serialize)]
pub struct StudyRow {
    /// (key, value) of every varied setting.
    pub parameters: Vec<(String, String)>,
    /// `finished`, `stopped`, `cancelled`, or `invalid` / `failed` with `message`.
    pub outcome: String,
    /// Wall seconds of the run.
    pub wall_seconds: Option<f64>,
    /// Steps taken.
    pub steps: Option<u64>,
    /// Particle count.
    pub particles: Option<usize>,
    /// Error against the scene's reference.
    pub error: Option<f64>,
    /// Energy drift.
    pub energy_drift: Option<f64>,
    /// Why the run did not happen or failed.
    pub message: Option<String>,
}

/// The (key, value) of every varied setting of one run.
pub type Labels = Vec<(String, String)>;

/// One run of a study: its `--set` overrides and their labels.
pub type Combination = (Vec<String>, Labels);

/// Every combination of the variations, as override lists with their (key, value) labels.
pub fn combinations(vars: &[Variation]) -> Vec<Combination> {
    let mut out = vec![(Vec::new(), Vec::new())];
    for v in vars {
        let mut next = Vec::new();
        for (sets, labels) in &out {
            for value in &v.values {
                let mut sets = sets.clone();
                let mut labels = labels.clone();
                for p in &v.paths {
                    sets.push(format!("{p}={value}"));
                }
                labels.push((v.key.clone(), value.clone()));
                next.push((sets, labels));
            }
        }
        out = next;
    }
    out
}

fn row_from_metrics(labels: Vec<(String, String)>, m: &serde_json::Value) -> StudyRow {
    StudyRow {
        parameters: labels,
        outcome: m["outcome"].as_str().unwrap_or("unknown").to_string(),
        wall_seconds: m["wall_seconds"].as_f64(),
        steps: m["steps"].as_u64(),
        particles: m["particles"].as_u64().map(|p| p as usize),
        error: m["error"].as_f64(),
        energy_drift: m["energy_drift"].as_f64(),
        message: m["diagnostic"]["message"].as_str().map(str::to_string),
    }
}

fn failed_row(labels: Vec<(String, String)>, outcome: &str, message: String) -> StudyRow {
    StudyRow {
        parameters: labels,
        outcome: outcome.to_string(),
        wall_seconds: None,
        steps: None,
        particles: None,
        error: None,
        energy_drift: None,
        message: Some(message),
    }
}

/// Runs every combination locally, `parallel` runs at a time (1: one after the other, each
/// with every core, so wall times compare; more: runs share the cores).
pub fn run_local(
    scene: &Path,
    vars: &[Variation],
    registry: &Registry,
    parallel: usize,
    progress: impl Fn(usize, usize, &[(String, String)]) + Sync,
) -> Vec<StudyRow> {
    let combos = combinations(vars);
    let total = combos.len();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let rows: Vec<std::sync::Mutex<Option<StudyRow>>> =
        (0..total).map(|_| std::sync::Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for _ in 0..parallel.clamp(1, total.max(1)) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some((sets, labels)) = combos.get(i) else {
                        break;
                    };
                    progress(i, total, labels);
                    let row = run_one(scene, sets, labels.clone(), registry);
                    *rows[i].lock().expect("study row lock") = Some(row);
                }
            });
        }
    });
    rows.into_iter()
        .map(|r| {
            r.into_inner()
                .expect("study row lock")
                .expect("every run recorded")
        })
        .collect()
}

fn run_one(scene: &Path, sets: &[String], labels: Labels, registry: &Registry) -> StudyRow {
    let validated = match load_scene(scene, sets, registry) {
        Ok(v) => v,
        Err(LoadError::Invalid(e)) => return failed_row(labels, "invalid", e.to_string()),
        Err(LoadError::Io(e)) => return failed_row(labels, "failed", format!("{e:#}")),
    };
    let result = mpm_core::solver::run_scene(
        &validated,
        &mut mpm_core::output::NullSink,
        &mut |_: &mpm_core::solver::Progress| mpm_core::solver::Control::Continue,
    );
    match result {
        Ok(m) => {
            let mut row = row_from_metrics(labels, &serde_json::to_value(&m).unwrap_or_default());
            if m.outcome == Some(Outcome::Finished) {
                row.message = None;
            }
            row
        }
        Err(e) => failed_row(labels, "invalid", e.to_string()),
    }
}

/// Submits every combination to a server as a group of jobs, waits, and reads the metrics.
pub fn run_remote(
    scene: &Path,
    vars: &[Variation],
    remote: &crate::client::Remote,
    progress: impl Fn(usize, usize, &[(String, String)]),
) -> anyhow::Result<Vec<StudyRow>> {
    let combos = combinations(vars);
    let total = combos.len();
    let mut submitted = Vec::new();
    for (i, (sets, labels)) in combos.into_iter().enumerate() {
        progress(i, total, &labels);
        match crate::client::submit(remote, scene, &sets) {
            Ok(job) => submitted.push((labels, Ok(job["id"].as_str().unwrap_or("").to_string()))),
            // The server refused this combination's scene: a row, and on to the next.
            Err(e) if ExitStatus::of_error(&e) == ExitStatus::InvalidInput => {
                submitted.push((labels, Err(format!("{e:#}"))))
            }
            // Unreadable scene, unreachable server: no use trying the other combinations.
            Err(e) => return Err(e),
        }
    }
    let mut rows = Vec::new();
    for (labels, id) in submitted {
        match id {
            Ok(id) => {
                let job = crate::client::wait(remote, &id, true)?;
                let mut row = row_from_metrics(labels, &job["metrics"]);
                if job["status"] != "succeeded" && row.message.is_none() {
                    row.message = job["failure"]["message"].as_str().map(str::to_string);
                }
                rows.push(row);
            }
            Err(message) => rows.push(failed_row(labels, "invalid", message)),
        }
    }
    Ok(rows)
}

fn opt(x: Option<f64>) -> String {
    x.map(|v| format!("{v:e}")).unwrap_or_default()
}

/// Writes `study.csv` and `study.json` into `dir`.
pub fn write_tables(dir: &Path, vars: &[Variation], rows: &[StudyRow]) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut csv = String::new();
    for v in vars {
        csv += &format!("{},", v.key);
    }
    csv += "outcome,wall_seconds,steps,particles,error,energy_drift,message\n";
    for r in rows {
        for (_, value) in &r.parameters {
            csv += &format!("{value},");
        }
        csv += &format!(
            "{},{},{},{},{},{},\"{}\"\n",
            r.outcome,
            opt(r.wall_seconds),
            r.steps.map(|s| s.to_string()).unwrap_or_default(),
            r.particles.map(|s| s.to_string()).unwrap_or_default(),
            opt(r.error),
            opt(r.energy_drift),
            r.message
                .as_deref()
                .unwrap_or("")
                .replace('"', "'")
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    std::fs::write(dir.join("study.csv"), csv)?;
    std::fs::write(dir.join("study.json"), serde_json::to_string_pretty(rows)?)?;
    Ok(())
}

/// A printable table of the rows.
pub fn table(vars: &[Variation], rows: &[StudyRow]) -> String {
    let mut out = String::new();
    for v in vars {
        out += &format!("{:>10} ", v.key);
    }
    out += &format!(
        "{:>9} {:>10} {:>7} {:>11} {:>11}\n",
        "outcome", "wall s", "steps", "error", "drift"
    );
    for r in rows {
        for (_, value) in &r.parameters {
            out += &format!("{value:>10} ");
        }
        out += &format!(
            "{:>9} {:>10} {:>7} {:>11} {:>11}\n",
            r.outcome,
            r.wall_seconds
                .map(|w| format!("{w:.3}"))
                .unwrap_or_default(),
            r.steps.map(|s| s.to_string()).unwrap_or_default(),
            r.error.map(|e| format!("{e:.3e}")).unwrap_or_default(),
            r.energy_drift
                .map(|e| format!("{e:+.2e}"))
                .unwrap_or_default(),
        );
    }
    out
}

/// Rows grouped into plot series: every varied setting except the refinement axes
/// (`cell_size`, `ppc`) names a series.
pub fn series(rows: &[StudyRow]) -> Vec<(String, Vec<&StudyRow>)> {
    let mut groups: Vec<(String, Vec<&StudyRow>)> = Vec::new();
    for r in rows
        .iter()
        .filter(|r| r.error.is_some() && r.wall_seconds.is_some())
    {
        let name: Vec<String> = r
            .parameters
            .iter()
            .filter(|(k, _)| k != "cell_size" && k != "ppc")
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        let name = if name.is_empty() {
            "runs".to_string()
        } else {
            name.join(" ")
        };
        match groups.iter_mut().find(|(n, _)| *n == name) {
            Some((_, g)) => g.push(r),
            None => groups.push((name, vec![r])),
        }
    }
    groups
}

/// Observed convergence order of a series: least-squares slope of log(error) against
/// log(cell_size), when the cell size varies within it.
pub fn observed_order(rows: &[&StudyRow]) -> Option<f64> {
    let points: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| {
            let h: f64 = r
                .parameters
                .iter()
                .find(|(k, _)| k == "cell_size")?
                .1
                .parse()
                .ok()?;
            let e = r.error?;
            (h > 0.0 && e > 0.0).then(|| (h.ln(), e.ln()))
        })
        .collect();
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = (
        points.iter().map(|p| p.0).sum::<f64>() / n,
        points.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// The runs no other run beats on both error and wall time, by increasing wall time.
pub fn pareto_front(rows: &[StudyRow]) -> Vec<&StudyRow> {
    let mut points: Vec<&StudyRow> = rows
        .iter()
        .filter(|r| r.error.is_some() && r.wall_seconds.is_some())
        .collect();
    points.sort_by(|a, b| {
        a.wall_seconds
            .partial_cmp(&b.wall_seconds)
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for r in points {
        let e = r.error.unwrap_or(f64::INFINITY);
        if e < best {
            best = e;
            front.push(r);
        }
    }
    front
}

/// Default output folder of a study of `scene`.
pub fn default_dir(scene: &Path) -> PathBuf {
    let stem = scene
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("scene");
    PathBuf::from("results").join(format!("{stem}-study"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(h: &str, kernel: &str, wall: f64, error: f64) -> StudyRow {
        StudyRow {
            parameters: vec![
                ("cell_size".into(), h.into()),
                ("kernel".into(), kernel.into()),
            ],
            outcome: "finished".into(),
            wall_seconds: Some(wall),
            steps: Some(1),
            particles: Some(1),
            error: Some(error),
            energy_drift: Some(0.0),
            message: None,
        }
    }

    #[test]
    fn combinations_cover_the_product_and_aliases_expand() {
        let vars = vec![
            parse_variation("cell_size=0.1,0.05", 2).unwrap(),
            parse_variation("ppc=1,2,3", 2).unwrap(),
        ];
        let combos = combinations(&vars);
        assert_eq!(combos.len(), 6);
        assert_eq!(
            combos[1].0,
            vec![
                "domain.cell_size=0.1",
                "bodies[0].particles_per_cell=2",
                "bodies[1].particles_per_cell=2"
            ]
        );
        assert!(parse_variation("cfl", 1).is_err());
    }

    #[test]
    fn order_and_pareto_front() {
        let rows = vec![
            row("0.1", "a", 1.0, 1e-2),
            row("0.05", "a", 2.0, 2.5e-3),
            row("0.1", "b", 1.5, 2e-2),
            row("0.05", "b", 0.5, 5e-2),
        ];
        let groups = series(&rows);
        assert_eq!(groups.len(), 2);
        let order = observed_order(&groups[0].1).unwrap();
        assert!((order - 2.0).abs() < 1e-12, "{order}");
        let front: Vec<f64> = pareto_front(&rows)
            .iter()
            .map(|r| r.wall_seconds.unwrap())
            .collect();
        assert_eq!(front, vec![0.5, 1.0, 2.0]);
    }
}
