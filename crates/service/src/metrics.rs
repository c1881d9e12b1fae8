//! Counters of this process for `/metrics`, written out by hand in the Prometheus text
//! exposition format (version 0.0.4): a few histograms and gauges do not need a crate.

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

#[derive(Default)]
struct Inner {
    queue_wait: Histogram,
    run_time: Histogram,
    finished: BTreeMap<String, u64>,
    heartbeats: BTreeMap<String, f64>,
    particle_steps: f64,
    run_seconds: f64,
    last_rate: f64,
    requests: BTreeMap<(String, u16), u64>,
}

/// This process's counters: jobs claimed and finished here, requests answered here.
#[derive(Default)]
pub struct Metrics {
    inner: Mutex<Inner>,
}

fn now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

impl Metrics {
    fn with(&self, f: impl FnOnce(&mut Inner)) {
        if let Ok(mut inner) = self.inner.lock() {
            f(&mut inner);
        }
    }

    /// A worker of this process started.
    pub fn worker_started(&self, worker: &str) {
        self.heartbeat(worker);
    }

    /// A worker of this process is alive (its loop turned or its lease was renewed).
    pub fn heartbeat(&self, worker: &str) {
        self.with(|i| {
            i.heartbeats.insert(worker.to_string(), now());
        });
    }

    /// A job was claimed after waiting `waited` seconds in the queue.
    pub fn claimed(&self, waited: f64) {
        self.with(|i| i.queue_wait.observe(waited));
    }

    /// A job ended in `status` after `wall` seconds of running and `particle_steps` work.
    pub fn finished(&self, status: &str, wall: f64, particle_steps: f64) {
        self.with(|i| {
            *i.finished.entry(status.to_string()).or_default() += 1;
            i.run_time.observe(wall);
            i.particle_steps += particle_steps;
            i.run_seconds += wall;
            if wall > 0.0 {
                i.last_rate = particle_steps / wall;
            }
        });
    }

    /// A request was answered.
    pub fn request(&self, method: &str, status: u16) {
        self.with(|i| *i.requests.entry((method.to_string(), status)).or_default() += 1);
    }

    /// The exposition text: `by_state` (jobs per status, from the database) and
    /// `running` (worker, seconds left of its lease, from the database) come from the caller.
    pub fn render(&self, by_state: &[(String, i64)], running: &[(String, f64)]) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "# HELP mpm_jobs Jobs in the queue database by state.\n# TYPE mpm_jobs gauge"
        );
        for state in ["queued", "running", "succeeded", "failed", "cancelled"] {
            let n = by_state
                .iter()
                .find(|(s, _)| s == state)
                .map_or(0, |(_, n)| *n);
            let _ = writeln!(out, "mpm_jobs{{state=\"{state}\"}} {n}");
        }
        let _ = writeln!(
            out,
            "# HELP mpm_running_job_lease_seconds Seconds left of each running job's lease, by worker (all workers of the database).\n# TYPE mpm_running_job_lease_seconds gauge"
        );
        for (worker, left) in running {
            let _ = writeln!(
                out,
                "mpm_running_job_lease_seconds{{worker=\"{}\"}} {left}",
                escape(worker)
            );
        }
        let Ok(i) = self.inner.lock() else {
            return out;
        };
        i.queue_wait.write(
            &mut out,
            "mpm_job_queue_wait_seconds",
            "Time from submission to claim of jobs claimed by this process's workers.",
        );
        i.run_time.write(
            &mut out,
            "mpm_job_run_seconds",
            "Run time of jobs finished by this process's workers.",
        );
        let _ = writeln!(
            out,
            "# HELP mpm_jobs_finished_total Jobs finished by this process's workers.\n# TYPE mpm_jobs_finished_total counter"
        );
        for (status, n) in &i.finished {
            let _ = writeln!(out, "mpm_jobs_finished_total{{status=\"{status}\"}} {n}");
        }
        let _ = writeln!(
            out,
            "# HELP mpm_worker_last_heartbeat_seconds Unix time of each worker's last heartbeat (this process's workers).\n# TYPE mpm_worker_last_heartbeat_seconds gauge"
        );
        for (worker, t) in &i.heartbeats {
            let _ = writeln!(
                out,
                "mpm_worker_last_heartbeat_seconds{{worker=\"{}\"}} {t}",
                escape(worker)
            );
        }
        let _ = writeln!(
            out,
            "# HELP mpm_particle_steps_total Particles times steps computed by this process's jobs.\n# TYPE mpm_particle_steps_total counter\nmpm_particle_steps_total {}",
            i.particle_steps
        );
        let rate = if i.run_seconds > 0.0 {
            i.particle_steps / i.run_seconds
        } else {
            0.0
        };
        let _ = writeln!(
            out,
            "# HELP mpm_particle_steps_per_second Particle-steps per second of run time, over all jobs of this process.\n# TYPE mpm_particle_steps_per_second gauge\nmpm_particle_steps_per_second {rate}"
        );
        let _ = writeln!(
            out,
            "# HELP mpm_last_job_particle_steps_per_second Particle-steps per second of the last job finished here.\n# TYPE mpm_last_job_particle_steps_per_second gauge\nmpm_last_job_particle_steps_per_second {}",
            i.last_rate
        );
        let _ = writeln!(
            out,
            "# HELP mpm_http_requests_total Requests answered by this process.\n# TYPE mpm_http_requests_total counter"
        );
        for ((method, status), n) in &i.requests {
            let _ = writeln!(
                out,
                "mpm_http_requests_total{{method=\"{method}\",status=\"{status}\"}} {n}"
            );
        }
        out
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

    #[test]
    fn histograms_are_cumulative_and_text_parses() {
        let m = Metrics::default();
        m.claimed(0.2);
        m.claimed(3.0);
        m.finished("succeeded", 2.0, 1000.0);
        let text = m.render(&[("queued".into(), 4)], &[("h:1:0".into(), 2.5)]);
        assert!(text.contains("mpm_jobs{state=\"queued\"} 4"));
        assert!(text.contains("mpm_jobs{state=\"failed\"} 0"));
        assert!(text.contains("mpm_job_queue_wait_seconds_bucket{le=\"0.25\"} 1"));
        assert!(text.contains("mpm_job_queue_wait_seconds_bucket{le=\"5\"} 2"));
        assert!(text.contains("mpm_job_queue_wait_seconds_count 2"));
        assert!(text.contains("mpm_particle_steps_per_second 500"));
        for line in text.lines().filter(|l| !l.starts_with('#')) {
            let value = line.rsplit(' ').next().unwrap();
            assert!(value.parse::<f64>().is_ok(), "{line}");
        }
    }
}
