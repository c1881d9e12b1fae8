//! The `mpm` client of the job service: submit, status, list, cancel, fetch, plugins.

use crate::exit_status::input_error;
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use reqwest::blocking::{Client, RequestBuilder, Response};
use serde_json::Value;
use std::io::IsTerminal;
use std::path::Path;
use std::time::Duration;

/// Where the server is and how to authenticate.
#[derive(Clone, Debug)]
pub struct Remote {
    /// Base URL, e.g. `http://127.0.0.1:8080`.
    pub server: String,
    /// Bearer token, when the server requires one.
    pub token: Option<String>,
}

impl Remote {
    fn client() -> anyhow::Result<Client> {
        Client::builder()
            .timeout(Duration::from_secs(60))
            .build()
            .context("creating the HTTP client")
    }

    fn request(&self, method: reqwest::Method, path: &str) -> anyhow::Result<RequestBuilder> {
        let url = format!("{}{}", self.server.trim_end_matches('/'), path);
        let mut r = Self::client()?.request(method, url);
        if let Some(t) = &self.token {
            r = r.bearer_auth(t);
        }
        Ok(r)
    }

    /// Sends a request; a non-success answer becomes an error worded as the server worded it.
    /// A 4xx answer (an invalid scene, an unknown job, a bad token) is invalid input (exit 2),
    /// except 408 and 429 (a timeout, a full queue), which are worth retrying (exit 1).
    fn send(&self, r: RequestBuilder) -> anyhow::Result<Response> {
        let response = r
            .send()
            .with_context(|| format!("cannot reach the server at {}", self.server))?;
        if response.status().is_success() {
            return Ok(response);
        }
        let status = response.status();
        let body: Value = response.json().unwrap_or(Value::Null);
        let error = &body["error"];
        let mut text = format!(
            "server answered {status}: {}",
            error["message"].as_str().unwrap_or("(no message)")
        );
        if let Some(problems) = error["problems"].as_array() {
            for p in problems {
                text += &format!(
                    "\n  {}: {}",
                    p["path"].as_str().unwrap_or("$"),
                    p["message"].as_str().unwrap_or("")
                );
            }
        }
        let code = status.as_u16();
        if status.is_client_error() && code != 408 && code != 429 {
            return Err(input_error!("{text}"));
        }
        bail!(text)
    }

    fn get_json(&self, path: &str) -> anyhow::Result<Value> {
        Ok(self
            .send(self.request(reqwest::Method::GET, path)?)?
            .json()?)
    }
}

/// Where a submitted job starts, when not from its scene: another job's stored state.
#[derive(Clone, Debug, Default)]
pub struct StartFrom {
    /// The job whose store holds the state (`--from`).
    pub job: Option<String>,
    /// The stage a staged scene starts at (`--stage`).
    pub stage: Option<String>,
}

/// Submits a scene file; returns the job.
pub fn submit(remote: &Remote, scene: &Path, overrides: &[String]) -> anyhow::Result<Value> {
    submit_from(remote, scene, overrides, &StartFrom::default())
}

/// Submits a scene file that starts from another job's stored state (`from=JOB`, with
/// `stage=NAME` for a staged scene); returns the job.
pub fn submit_from(
    remote: &Remote,
    scene: &Path,
    overrides: &[String],
    start: &StartFrom,
) -> anyhow::Result<Value> {
    let text = std::fs::read_to_string(scene)
        .with_context(|| format!("cannot read scene file `{}`", scene.display()))?;
    let mut value: Value = serde_json::from_str(&text)
        .map_err(|e| input_error!("{}: $: not valid JSON: {e}", scene.display()))?;
    for o in overrides {
        crate::overrides::apply_override(&mut value, o)
            .map_err(|e| input_error!("{}: --set: {e:#}", scene.display()))?;
    }
    let query: Vec<String> = [("from", &start.job), ("stage", &start.stage)]
        .into_iter()
        .filter_map(|(key, value)| Some(format!("{key}={}", url_escaped(value.as_deref()?))))
        .collect();
    let path = match query.is_empty() {
        true => "/v1/jobs".to_string(),
        false => format!("/v1/jobs?{}", query.join("&")),
    };
    let r = remote.request(reqwest::Method::POST, &path)?.json(&value);
    Ok(remote.send(r)?.json()?)
}

/// `text` with every byte but the unreserved characters of RFC 3986 percent-encoded, for a
/// query value.
fn url_escaped(text: &str) -> String {
    text.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' => {
                (b as char).to_string()
            }
            _ => format!("%{b:02X}"),
        })
        .collect()
}

/// One job.
pub fn status(remote: &Remote, id: &str) -> anyhow::Result<Value> {
    remote.get_json(&format!("/v1/jobs/{id}"))
}

/// Jobs, optionally of one status.
pub fn list(remote: &Remote, status: Option<&str>) -> anyhow::Result<Value> {
    match status {
        Some(s) => remote.get_json(&format!("/v1/jobs?status={s}&limit=1000")),
        None => remote.get_json("/v1/jobs?limit=1000"),
    }
}

/// Cancels a job.
pub fn cancel(remote: &Remote, id: &str) -> anyhow::Result<Value> {
    let r = remote.request(reqwest::Method::DELETE, &format!("/v1/jobs/{id}"))?;
    Ok(remote.send(r)?.json()?)
}

/// The server's plugins.
pub fn plugins(remote: &Remote) -> anyhow::Result<Value> {
    remote.get_json("/v1/plugins")
}

/// Polls a job until it ends, showing a progress bar fed by the server; returns the job.
pub fn wait(remote: &Remote, id: &str, quiet: bool) -> anyhow::Result<Value> {
    let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = ProgressBar::new(1000);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {percent:>3}% {msg} [{elapsed_precise}]")
                .expect("valid template"),
        );
        bar
    });
    let mut last_line = -1i64;
    loop {
        let job = status(remote, id)?;
        let state = job["status"].as_str().unwrap_or("?").to_string();
        let fraction = job["progress"]["fraction"].as_f64().unwrap_or(0.0);
        let steps = job["progress"]["steps"].as_i64().unwrap_or(0);
        let eta = job["progress"]["eta_seconds"]
            .as_f64()
            .map(|e| format!(", eta {e:.0} s"))
            .unwrap_or_default();
        if let Some(bar) = &bar {
            bar.set_position((fraction * 1000.0) as u64);
            bar.set_message(format!("{state}, step {steps}{eta}"));
        } else if !quiet && (fraction * 10.0) as i64 > last_line {
            last_line = (fraction * 10.0) as i64;
            eprintln!("{state} {:>3.0}% step {steps}{eta}", fraction * 100.0);
        }
        if matches!(state.as_str(), "succeeded" | "failed" | "cancelled") {
            if let Some(bar) = &bar {
                bar.finish_and_clear();
            }
            return Ok(job);
        }
        std::thread::sleep(Duration::from_millis(250));
    }
}

/// Downloads a job's result store into `out/<name>.zarr`; returns its path.
pub fn fetch(remote: &Remote, id: &str, out: &Path) -> anyhow::Result<std::path::PathBuf> {
    let job = status(remote, id)?;
    let name = job["name"].as_str().unwrap_or("results").to_string();
    let files = remote.get_json(&format!("/v1/jobs/{id}/files"))?;
    let files = files["files"].as_array().cloned().unwrap_or_default();
    if files.is_empty() {
        bail!("job {id} has no results yet (status {})", job["status"]);
    }
    let target = out.join(format!("{name}.zarr"));
    for f in files {
        let rel = f.as_str().context("file list entry is not a string")?;
        // The server lists paths inside the store; refuse anything else.
        let safe = std::path::Path::new(rel)
            .components()
            .all(|c| matches!(c, std::path::Component::Normal(_)));
        if !safe {
            bail!("the server listed an unsafe path `{rel}`");
        }
        let bytes = remote
            .send(remote.request(
                reqwest::Method::GET,
                &format!("/v1/jobs/{id}/results/{rel}"),
            )?)?
            .bytes()?;
        let path = target.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating {}", parent.display()))?;
        }
        std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(target)
}

/// One line per job for `mpm list`.
pub fn job_line(job: &Value) -> String {
    format!(
        "{}  {:<9}  {:>5.1}%  {}",
        job["id"].as_str().unwrap_or("?"),
        job["status"].as_str().unwrap_or("?"),
        job["progress"]["fraction"].as_f64().unwrap_or(0.0) * 100.0,
        job["name"].as_str().unwrap_or("?")
    )
}
