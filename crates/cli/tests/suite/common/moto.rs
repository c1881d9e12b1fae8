//! An S3-compatible server of a test's own: moto's `moto_server` (PyPI `moto[server]`, pinned
//! in tests/python/requirements.txt) on a free loopback port, killed when dropped.

use super::Process;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The `moto_server` program: `$MPM_MOTO_SERVER`, else the repository's `.venv` (which
/// `.ci/run` creates before `cargo test`).
pub fn moto_server() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("MPM_MOTO_SERVER").map(PathBuf::from) {
        return path.is_file().then_some(path);
    }
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/bin/moto_server");
    venv.is_file().then_some(venv)
}

/// A running moto server.
pub struct Moto {
    /// The server process (SIGKILL when dropped, also when the test fails).
    _process: Process,
    /// Its loopback port.
    pub port: u16,
}

impl Moto {
    /// Starts `bin` on a free loopback port and waits until it answers HTTP.
    pub fn start(bin: &Path) -> Moto {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let process = Process(
            Command::new(bin)
                .args(["-H", "127.0.0.1", "-p", &port.to_string()])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("moto_server starts"),
        );
        let moto = Moto {
            _process: process,
            port,
        };
        let client = super::http_client(5);
        let since = Instant::now();
        while client.get(moto.endpoint()).send().is_err() {
            assert!(
                since.elapsed() < Duration::from_secs(60),
                "moto_server did not answer on port {port}"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        moto
    }

    /// CPU seconds the server has used so far (Linux: /proc), to see what the S3 requests
    /// cost; `None` where that cannot be read.
    pub fn cpu_seconds(&self) -> Option<f64> {
        let stat = std::fs::read_to_string(format!("/proc/{}/stat", self._process.0.id())).ok()?;
        // Fields after the command name (which may hold spaces) start at `) `.
        let fields: Vec<&str> = stat.rsplit_once(") ")?.1.split(' ').collect();
        let ticks: f64 =
            fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
        Some(ticks / 100.0)
    }

    /// `http://127.0.0.1:PORT`.
    pub fn endpoint(&self) -> String {
        format!("http://127.0.0.1:{}", self.port)
    }

    /// Sets the AWS variables that point `mpm` at this server (moto takes any keys).
    pub fn env<'a>(&self, command: &'a mut Command) -> &'a mut Command {
        command
            .env("AWS_ENDPOINT_URL", self.endpoint())
            .env("AWS_ACCESS_KEY_ID", "testing")
            .env("AWS_SECRET_ACCESS_KEY", "testing")
            .env("AWS_REGION", "us-east-1")
            .env_remove("AWS_ENDPOINT_URL_S3")
            .env_remove("AWS_SESSION_TOKEN")
    }

    /// Creates a bucket with the S3 API's CreateBucket (`PUT /BUCKET`; moto needs no
    /// signature).
    pub fn create_bucket(&self, bucket: &str) {
        let r = super::http_client(30)
            .put(format!("{}/{bucket}", self.endpoint()))
            .send()
            .unwrap();
        assert!(r.status().is_success(), "CreateBucket: {}", r.status());
    }

    /// The keys of the objects under `prefix` in `bucket` (ListObjectsV2, every page).
    pub fn keys(&self, bucket: &str, prefix: &str) -> Vec<String> {
        let mut keys = Vec::new();
        let mut token: Option<String> = None;
        loop {
            let mut url = format!(
                "{}/{bucket}?list-type=2&prefix={}",
                self.endpoint(),
                encode(prefix)
            );
            if let Some(t) = &token {
                url.push_str(&format!("&continuation-token={}", encode(t)));
            }
            let body = super::http_client(30)
                .get(url)
                .send()
                .unwrap()
                .text()
                .unwrap();
            keys.extend(elements(&body, "Key"));
            token = elements(&body, "NextContinuationToken").into_iter().next();
            if token.is_none() {
                break;
            }
        }
        keys
    }
}

/// `text` percent-encoded for a query string (every byte but the unreserved ones).
fn encode(text: &str) -> String {
    text.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' => {
                (b as char).to_string()
            }
            _ => format!("%{b:02X}"),
        })
        .collect()
}

/// The texts of every `<name>...</name>` element of an XML document (keys here are plain).
fn elements(xml: &str, name: &str) -> Vec<String> {
    let (open, close) = (format!("<{name}>"), format!("</{name}>"));
    xml.split(&open)
        .skip(1)
        .filter_map(|s| s.split_once(&close).map(|(t, _)| t.to_string()))
        .collect()
}
