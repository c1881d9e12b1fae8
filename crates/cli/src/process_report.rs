//! The process report `mpm run` prints after a staged run's summary: per stage, what the
//! fill left (fill time, voids), the peak von Mises stress of each material, and damage
//! (failed particles, cracks, the longest crack, the first failure), the inelastic work of
//! a solder law with its fatigue life; then where the first crack started and the life the
//! last stage (cycle) gives. Every figure is also in the run's metrics (`stages[i]`), which the job
//! service stores with the job; `mpm submit --wait` prints the same report from them.

use mpm_core::damage_measures::{DamageFigures, SITE_DAMAGE};
use mpm_core::fatigue_measures::FatigueFigures;
use mpm_core::output::{Metrics, StageSummary};

/// The report's lines (empty for a run without stages).
pub(crate) fn process_report(m: &Metrics) -> Vec<String> {
    let mut lines = Vec::new();
    for stage in &m.stages {
        let name = &stage.name;
        if let Some(fill) = fill_line(stage) {
            lines.push(format!("{name}: {fill}"));
        }
        // A stage without mechanics (a fill) has no stress to report.
        if stage.peak_von_mises.values().any(|s| *s > 0.0) {
            let peaks: Vec<String> = stage
                .peak_von_mises
                .iter()
                .map(|(material, s)| format!("{material} {:.1}", s / 1e6))
                .collect();
            lines.push(format!("{name}: peak von Mises, MPa: {}", peaks.join(", ")));
        }
        for (material, d) in stage.damage.iter().filter(|(_, d)| d.peak > 0.0) {
            lines.push(format!("{name}: {}", damage_line(material, d)));
        }
        for (material, f) in stage
            .fatigue
            .iter()
            .filter(|(_, f)| f.whole.work_in_stage > 0.0)
        {
            lines.push(format!("{name}: {}", fatigue_line(material, f)));
        }
    }
    let first = m.stages.iter().enumerate().find_map(|(index, stage)| {
        stage
            .damage
            .iter()
            .filter_map(|(material, d)| d.onset.map(|o| (material, o)))
            .min_by(|a, b| a.1.time.total_cmp(&b.1.time))
            .map(|(material, o)| (index, stage, material, o))
    });
    if !m.stages.is_empty() && m.stages.iter().any(|s| !s.damage.is_empty()) {
        lines.push(match first {
            Some((index, stage, material, o)) => format!(
                "crack onset: stage {} ({} of {}), {material}, t = {:.6e} s at {}",
                stage.name,
                index + 1,
                m.stages.len(),
                o.time,
                position(&o.position)
            ),
            None => "crack onset: none (no particle failed)".to_string(),
        });
    }
    if let Some(last) = m.stages.last() {
        for (material, f) in &last.fatigue {
            let failure =
                |n: Option<f64>| n.map_or(String::new(), |n| format!(", {n:.0} to failure"));
            if let Some(n) = f.whole.cycles_to_crack {
                lines.push(format!(
                    "fatigue life: {material}, {n:.0} cycles to crack initiation{} at the work per cycle of stage {}",
                    failure(f.whole.cycles_to_failure),
                    last.name
                ));
            }
            if let Some((along, layer)) = f.critical_layer()
                && let Some(n) = layer.figures.cycles_to_crack
            {
                lines.push(format!(
                    "fatigue life at the interface layer: {material} by {along}, {n:.0} cycles{} at the work per cycle of stage {}",
                    failure(layer.figures.cycles_to_failure),
                    last.name
                ));
            }
        }
    }
    lines
}

/// One material's inelastic work in a stage, and the cycles to crack it gives
/// (`solder inelastic work 0.0123 MJ/m³ in the stage, 0.456 in all; 4321 cycles ...`).
fn fatigue_line(material: &str, f: &FatigueFigures) -> String {
    let mut line = format!(
        "{material} inelastic work {:.4} MJ/m³ in the stage ({:.4} in all, volume average)",
        f.whole.work_in_stage / 1e6,
        f.whole.work / 1e6
    );
    if let Some(n) = f.whole.cycles_to_crack {
        line += &format!("; {n:.0} cycles to crack initiation were every cycle like it");
    }
    if let Some(n) = f.whole.cycles_to_failure {
        line += &format!(", {n:.0} to failure");
    }
    for (along, layer) in &f.layers {
        line += &format!(
            "; its layer by {along} {:.4} MJ/m³",
            layer.figures.work_in_stage / 1e6
        );
        if let Some(n) = layer.figures.cycles_to_crack {
            line += &format!(", {n:.0} cycles");
        }
        if let Some(n) = layer.figures.cycles_to_failure {
            line += &format!(" ({n:.0} to failure)");
        }
    }
    line
}

/// The report of a job's metrics as the service stores them (JSON): `mpm submit --wait`
/// prints it below the metrics. Empty for a job without stages.
pub(crate) fn job_report(metrics: &serde_json::Value) -> Vec<String> {
    let stages: Vec<StageSummary> =
        serde_json::from_value(metrics["stages"].clone()).unwrap_or_default();
    process_report(&Metrics {
        stages,
        ..Metrics::default()
    })
}

/// One material's damage: the largest, the failed particles, their cracks and the first
/// failure (`underfill damage 1.000, 37 failed in 2 crack(s), longest ...`).
pub(crate) fn damage_line(material: &str, d: &DamageFigures) -> String {
    let mut line = format!(
        "{material} damage {:.3}, {} failed",
        d.peak, d.failed_particles
    );
    if d.failed_particles > 0 {
        line += &format!(
            " in {} crack(s), longest {:.4e} m",
            d.cracks, d.crack_length
        );
    }
    if let Some(o) = &d.onset {
        line += &format!(
            "; first failure t = {:.6e} s at {}",
            o.time,
            position(&o.position)
        );
    }
    if !d.sites.is_empty() {
        let sites: Vec<String> = d
            .sites
            .iter()
            .map(|s| {
                format!(
                    "{:.3} about {}, {} of {} failed",
                    s.peak,
                    position(&s.centre),
                    s.failed_particles,
                    s.particles
                )
            })
            .collect();
        line += &format!("; sites at damage ≥ {SITE_DAMAGE}: {}", sites.join("; "));
    }
    line
}

/// What a fill stage reports: fill time, voids and trapped air, when it has them.
fn fill_line(stage: &StageSummary) -> Option<String> {
    let p = &stage.physics;
    let mut parts = Vec::new();
    if let Some(t) = p.get("underfill.fill_time") {
        parts.push(format!("fill time {t:.6e} s"));
    }
    if let Some(f) = p.get("underfill.fill_fraction") {
        parts.push(format!("filled {:.2}%", 100.0 * f));
    }
    if let Some(v) = p.get("underfill.voids") {
        parts.push(format!("{v} void(s) at most"));
    }
    if let Some(a) = p.get("underfill.trapped_air_area") {
        parts.push(format!("trapped air at most {a:.4e} m²"));
    }
    if let Some(v) = p.get("underfill.trapped_air_volume") {
        parts.push(format!("trapped air at most {v:.4e} m³"));
    }
    if let Some(v) = p.get("underfill.voids_left") {
        let volume = p.get("underfill.trapped_air_left").copied().unwrap_or(0.0);
        parts.push(format!(
            "{v} void(s) left at its end holding {volume:.4e} m³ of air"
        ));
    }
    if stage.removed_particles > 0 {
        parts.push(format!(
            "{} particles removed at its start",
            stage.removed_particles
        ));
    }
    (!parts.is_empty()).then(|| parts.join(", "))
}

/// A position in m, with z left out when it is 0 (2D).
fn position(x: &[f64; 3]) -> String {
    if x[2] == 0.0 {
        format!("({:.4e}, {:.4e}) m", x[0], x[1])
    } else {
        format!("({:.4e}, {:.4e}, {:.4e}) m", x[0], x[1], x[2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mpm_core::damage_measures::{DamageSite, FailureOnset};
    use mpm_core::fatigue_measures::{LayerFigures, WorkFigures};

    fn stage(name: &str, onset: Option<f64>) -> StageSummary {
        let mut s = StageSummary {
            name: name.into(),
            ..StageSummary::default()
        };
        s.peak_von_mises.insert("silicon".into(), 2.5e8);
        s.damage.insert(
            "underfill".into(),
            DamageFigures {
                peak: if onset.is_some() { 1.0 } else { 0.5 },
                failed_particles: usize::from(onset.is_some()) * 4,
                cracks: usize::from(onset.is_some()),
                crack_length: 4e-5,
                onset: onset.map(|time| FailureOnset {
                    time,
                    position: [1e-4, 2e-4, 0.0],
                    particle: 7,
                }),
                sites: onset
                    .map(|_| {
                        vec![
                            DamageSite {
                                peak: 1.0,
                                centre: [1e-4, 2e-4, 0.0],
                                particles: 6,
                                failed_particles: 4,
                            },
                            DamageSite {
                                peak: 0.69,
                                centre: [4e-5, 1.5e-4, 0.0],
                                particles: 3,
                                failed_particles: 0,
                            },
                        ]
                    })
                    .unwrap_or_default(),
                ..DamageFigures::default()
            },
        );
        s
    }

    #[test]
    fn a_fill_stage_reports_its_fill_time_and_the_voids_it_left() {
        let mut fill = StageSummary {
            name: "fill".into(),
            ..StageSummary::default()
        };
        for (name, value) in [
            ("underfill.fill_time", 2.5e-3),
            ("underfill.fill_fraction", 0.9356),
            ("underfill.voids", 12.0),
            ("underfill.voids_left", 7.0),
            ("underfill.trapped_air_left", 3e-14),
        ] {
            fill.physics.insert(name.into(), value);
        }
        let m = Metrics {
            stages: vec![fill],
            ..Metrics::default()
        };
        assert_eq!(
            process_report(&m),
            [
                "fill: fill time 2.500000e-3 s, filled 93.56%, 12 void(s) at most, 7 void(s) left \
                 at its end holding 3.0000e-14 m³ of air"
            ]
        );
    }

    #[test]
    fn the_report_names_the_stage_a_crack_started_in() {
        let m = Metrics {
            stages: vec![stage("cure", None), stage("cycle-1", Some(3900.0))],
            ..Metrics::default()
        };
        let lines = process_report(&m);
        assert!(lines.contains(&"cure: peak von Mises, MPa: silicon 250.0".to_string()));
        assert!(lines.contains(&"cure: underfill damage 0.500, 0 failed".to_string()));
        assert!(
            lines.contains(
                &"cycle-1: underfill damage 1.000, 4 failed in 1 crack(s), longest 4.0000e-5 m; \
              first failure t = 3.900000e3 s at (1.0000e-4, 2.0000e-4) m; sites at damage ≥ \
              0.5: 1.000 about (1.0000e-4, 2.0000e-4) m, 4 of 6 failed; 0.690 about \
              (4.0000e-5, 1.5000e-4) m, 0 of 3 failed"
                    .to_string()
            )
        );
        assert_eq!(
            lines.last().unwrap(),
            "crack onset: stage cycle-1 (2 of 2), underfill, t = 3.900000e3 s at \
             (1.0000e-4, 2.0000e-4) m"
        );
        let whole = Metrics {
            stages: vec![stage("cure", None)],
            ..Metrics::default()
        };
        assert_eq!(
            process_report(&whole).last().unwrap(),
            "crack onset: none (no particle failed)"
        );
        assert!(process_report(&Metrics::default()).is_empty());
        // A job's stored metrics give the same report.
        let stored = serde_json::to_value(&m).unwrap();
        assert_eq!(job_report(&stored), lines);
        assert!(job_report(&serde_json::json!({"outcome": "finished"})).is_empty());
    }

    #[test]
    fn a_solder_stage_reports_its_inelastic_work_and_the_life_it_gives() {
        let mut cycle = stage("cycle-1", None);
        cycle.fatigue.insert(
            "solder".into(),
            FatigueFigures {
                whole: WorkFigures {
                    work: 0.5e6,
                    work_in_stage: 0.2e6,
                    cycles_to_crack: Some(2631.6),
                    cycles_to_failure: Some(2828.0),
                },
                layers: [(
                    "silicon".to_string(),
                    LayerFigures {
                        figures: WorkFigures {
                            work: 0.9e6,
                            work_in_stage: 0.4e6,
                            cycles_to_crack: Some(1315.8),
                            cycles_to_failure: Some(1420.2),
                        },
                        volume: 1e-9,
                    },
                )]
                .into(),
            },
        );
        let lines = process_report(&Metrics {
            stages: vec![cycle],
            ..Metrics::default()
        });
        assert!(
            lines.contains(
                &"cycle-1: solder inelastic work 0.2000 MJ/m³ in the stage (0.5000 in all, volume \
              average); 2632 cycles to crack initiation were every cycle like it, 2828 to failure; \
              its layer by silicon 0.4000 MJ/m³, 1316 cycles (1420 to failure)"
                    .to_string()
            ),
            "{lines:?}"
        );
        assert_eq!(
            lines[lines.len() - 2..],
            [
                "fatigue life: solder, 2632 cycles to crack initiation, 2828 to failure at the \
                 work per cycle of stage cycle-1",
                "fatigue life at the interface layer: solder by silicon, 1316 cycles, 1420 to \
                 failure at the work per cycle of stage cycle-1"
            ]
        );
    }
}
