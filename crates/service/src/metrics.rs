//! `/metrics`, written out by hand in the Prometheus text exposition format (version 0.0.4):
//! a few histograms and gauges do not need a crate. Jobs and workers come from the database
//! (every machine's), requests from this process.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;

/// Upper bounds of the histogram buckets, seconds (queue wait and run time alike).
const BUCKETS: [f64; 12] = [
    0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 300.0, 1800.0, 7200.0,
];

/// A cumulative histogram.
#[derive(Default, Clone)]
struct Histogram {
    counts: [u64; BUCKETS.len()],
    count: u64,
    sum: f64,
}

impl Histogram {
    fn observe(&mut self, v: f64) {
        for (c, b) in self.counts.iter_mut().zip(BUCKETS) {
            if v <= b {
                *c += 1;
            }
        }
        self.count += 1;
        self.sum += v;
    }

    fn write(&self, out: &mut String, name: &str, help: &str) {
        let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} histogram");
        for (c, b) in self.counts.iter().zip(BUCKETS) {
            let _ = writeln!(out, "{name}_bucket{{le=\"{b}\"}} {c}");
        }
        let _ = writeln!(out, "{name}_bucket{{le=\"+Inf\"}} {}", self.count);
        let _ = writeln!(out, "{name}_sum {}", self.sum);
        let _ = writeln!(out, "{name}_count {}", self.count);
    }
}

/// What `/metrics` shows, read from the database at each scrape (so every worker and job of
/// the queue, whichever machine ran it).
pub struct Snapshot {
    /// Jobs per status.
    pub by_state: Vec<(String, i64)>,
    /// Worker and seconds left of its lease, per running job.
    pub running: Vec<(String, f64)>,
    /// Worker and the epoch seconds of its last heartbeat.
    pub workers: Vec<(String, f64)>,
    /// The database's clock, epoch seconds.
    pub now: f64,
    /// Times of the jobs that were claimed.
    pub jobs: Vec<crate::db::JobTimes>,
}

/// This process's own counters (requests it answered).
#[derive(Default)]
pub struct Metrics {
    requests: Mutex<BTreeMap<(String, u16), u64>>,
}

impl Metrics {
    /// A request was answered.
    pub fn request(&self, method: &str, status: u16) {
        if let Ok(mut r) = self.requests.lock() {
            *r.entry((method.to_string(), status)).or_default() += 1;
        }
    }

    /// The exposition text of `snapshot` and this process's counters.
    pub fn render(&self, snapshot: &Snapshot) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "# HELP mpm_jobs Jobs in the queue by state.\n# TYPE mpm_jobs gauge"
        );
        for state in ["queued", "running", "succeeded", "failed", "cancelled"] {
            let n = snapshot
                .by_state
                .iter()
                .find(|(s, _)| s == state)
                .map_or(0, |(_, n)| *n);
            let _ = writeln!(out, "mpm_jobs{{state=\"{state}\"}} {n}");
        }
        per_worker(
            &mut out,
            "mpm_running_job_lease_seconds",
            "Seconds left of each running job's lease, by worker.",
            snapshot.running.iter().map(|(w, left)| (w.as_str(), *left)),
        );
        per_worker(
            &mut out,
            "mpm_worker_last_heartbeat_seconds",
            "Unix time of each worker's last heartbeat (workers stopped cleanly are removed; a dead one's stays behind).",
            snapshot.workers.iter().map(|(w, t)| (w.as_str(), *t)),
        );
        per_worker(
            &mut out,
            "mpm_worker_heartbeat_age_seconds",
            "Seconds since each worker's last heartbeat, on the database's clock.",
            snapshot
                .workers
                .iter()
                .map(|(w, t)| (w.as_str(), (snapshot.now - t).max(0.0))),
        );
        let mut wait = Histogram::default();
        let mut run = Histogram::default();
        let (mut particle_steps, mut run_seconds) = (0.0, 0.0);
        for j in &snapshot.jobs {
            if let Some(w) = j.waited {
                wait.observe(w);
            }
            if matches!(j.status.as_str(), "succeeded" | "failed" | "cancelled") {
                run.observe(j.wall_seconds);
                particle_steps += j.particle_steps;
                run_seconds += j.wall_seconds;
            }
        }
        wait.write(
            &mut out,
            "mpm_job_queue_wait_seconds",
            "Time from submission to the (last) claim of every claimed job.",
        );
        run.write(
            &mut out,
            "mpm_job_run_seconds",
            "Wall time of the (last) run of every ended job.",
        );
        let rate = if run_seconds > 0.0 {
            particle_steps / run_seconds
        } else {
            0.0
        };
        let _ = writeln!(
            out,
            "# HELP mpm_particle_steps_total Particles times steps of the ended jobs' runs.\n# TYPE mpm_particle_steps_total counter\nmpm_particle_steps_total {particle_steps}"
        );
        let _ = writeln!(
            out,
            "# HELP mpm_particle_steps_per_second Particle-steps per second of run time over the ended jobs.\n# TYPE mpm_particle_steps_per_second gauge\nmpm_particle_steps_per_second {rate}"
        );
        let _ = writeln!(
            out,
            "# HELP mpm_http_requests_total Requests answered by this process.\n# TYPE mpm_http_requests_total counter"
        );
        if let Ok(requests) = self.requests.lock() {
            for ((method, status), n) in requests.iter() {
                let _ = writeln!(
                    out,
                    "mpm_http_requests_total{{method=\"{method}\",status=\"{status}\"}} {n}"
                );
            }
        }
        out
    }
}

/// A gauge family with one sample per worker.
fn per_worker<'a>(
    out: &mut String,
    name: &str,
    help: &str,
    rows: impl Iterator<Item = (&'a str, f64)>,
) {
    let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} gauge");
    for (worker, value) in rows {
        let _ = writeln!(out, "{name}{{worker=\"{}\"}} {value}", escape(worker));
    }
}

/// Escapes a label value (backslash, quote, newline).
fn escape(v: &str) -> String {
    v.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::JobTimes;

    #[test]
    fn histograms_are_cumulative_and_text_parses() {
        let m = Metrics::default();
        m.request("GET", 200);
        let job = |status: &str, waited: f64, wall: f64| JobTimes {
            status: status.into(),
            waited: Some(waited),
            wall_seconds: wall,
            particle_steps: 1000.0 * wall,
        };
        let text = m.render(&Snapshot {
            by_state: vec![("queued".into(), 4)],
            running: vec![("h:1:0".into(), 2.5)],
            workers: vec![("h:1:0".into(), 100.0)],
            now: 103.0,
            jobs: vec![job("succeeded", 0.2, 2.0), job("running", 3.0, 0.5)],
        });
        assert!(text.contains("mpm_jobs{state=\"queued\"} 4"));
        assert!(text.contains("mpm_jobs{state=\"failed\"} 0"));
        assert!(text.contains("mpm_job_queue_wait_seconds_bucket{le=\"0.25\"} 1"));
        assert!(text.contains("mpm_job_queue_wait_seconds_bucket{le=\"5\"} 2"));
        assert!(text.contains("mpm_job_queue_wait_seconds_count 2"));
        assert!(
            text.contains("mpm_job_run_seconds_count 1"),
            "running jobs have no run time yet"
        );
        assert!(text.contains("mpm_particle_steps_per_second 1000"));
        assert!(text.contains("mpm_worker_heartbeat_age_seconds{worker=\"h:1:0\"} 3"));
        assert!(text.contains("mpm_http_requests_total{method=\"GET\",status=\"200\"} 1"));
        for line in text.lines().filter(|l| !l.starts_with('#')) {
            let value = line.rsplit(' ').next().unwrap();
            assert!(value.parse::<f64>().is_ok(), "{line}");
        }
    }
}
