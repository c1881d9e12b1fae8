//! A PostgreSQL server of a test's own (initdb in a temporary folder, a free loopback port,
//! the socket in that folder; as root the server runs as the `postgres` user through
//! `runuser`), for the tests of the service on several processes.

use super::text;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The folder holding `initdb`, `pg_ctl`, `createdb` and `psql`: `$PG_BIN`, else the newest
/// `/usr/lib/postgresql/*/bin` (Debian), else the folder of `pg_ctl` on the PATH.
pub fn postgres_bin() -> Option<PathBuf> {
    let has_all = |dir: &Path| {
        ["initdb", "pg_ctl", "createdb", "psql"]
            .iter()
            .all(|b| dir.join(b).is_file())
    };
    if let Some(dir) = std::env::var_os("PG_BIN").map(PathBuf::from) {
        return has_all(&dir).then_some(dir);
    }
    let mut debian: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let version = e.file_name().to_str()?.parse::<u32>().ok()?;
            Some((version, e.path().join("bin")))
        })
        .filter(|(_, dir)| has_all(dir))
        .collect();
    debian.sort();
    if let Some((_, dir)) = debian.pop() {
        return Some(dir);
    }
    std::env::var_os("PATH").and_then(|path| std::env::split_paths(&path).find(|dir| has_all(dir)))
}

/// A PostgreSQL server of this test; stopped (immediately) and deleted when dropped, also
/// when the test fails.
pub struct Postgres {
    bin: PathBuf,
    dir: tempfile::TempDir,
    /// Runs the server's commands as this user (PostgreSQL refuses to run as root).
    user: Option<String>,
    port: u16,
}

pub fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

impl Postgres {
    fn command(&self, program: &str) -> Command {
        let path = self.bin.join(program);
        match &self.user {
            Some(user) => {
                let mut c = Command::new("runuser");
                c.args(["-u", user, "--"]).arg(path);
                c
            }
            None => Command::new(path),
        }
    }

    pub fn start(bin: PathBuf) -> Postgres {
        let dir = tempfile::tempdir().unwrap();
        // As root: the server runs as `postgres` (the Debian package's user), which must own
        // the folder.
        let user = is_root().then(|| "postgres".to_string());
        if let Some(user) = &user {
            let status = Command::new("chown")
                .arg(user)
                .arg(dir.path())
                .status()
                .unwrap();
            assert!(
                status.success(),
                "chown {user} failed: is there a `{user}` user?"
            );
        }
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let pg = Postgres {
            bin,
            dir,
            user,
            port,
        };
        let data = pg.dir.path().join("data");
        let o = pg
            .command("initdb")
            .args(["-A", "trust", "-U", "mpm", "-E", "UTF8", "--no-sync", "-D"])
            .arg(&data)
            .output()
            .unwrap();
        assert!(o.status.success(), "initdb: {}", text(&o));
        let options = format!(
            "-p {port} -k {} -c listen_addresses=127.0.0.1 -c fsync=off \
             -c synchronous_commit=off -c full_page_writes=off",
            pg.dir.path().display()
        );
        let o = pg
            .command("pg_ctl")
            .args(["-w", "-t", "60", "-D"])
            .arg(&data)
            .args(["-o", &options, "-l"])
            .arg(pg.dir.path().join("server.log"))
            .arg("start")
            .output()
            .unwrap();
        assert!(o.status.success(), "pg_ctl start: {}", text(&o));
        let o = pg
            .command("createdb")
            .args([
                "-h",
                "127.0.0.1",
                "-p",
                &port.to_string(),
                "-U",
                "mpm",
                "mpm",
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "createdb: {}", text(&o));
        pg
    }

    pub fn url(&self) -> String {
        format!("postgres://mpm@127.0.0.1:{}/mpm", self.port)
    }

    /// Rows of a query, columns split on `|`.
    pub fn query(&self, sql: &str) -> Vec<Vec<String>> {
        let o = Command::new(self.bin.join("psql"))
            .args(["-h", "127.0.0.1", "-p", &self.port.to_string(), "-U", "mpm"])
            .args(["-d", "mpm", "-A", "-t", "-F", "|", "-c", sql])
            .output()
            .unwrap();
        assert!(o.status.success(), "psql: {}", text(&o));
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter(|l| !l.is_empty())
            .map(|l| l.split('|').map(str::to_string).collect())
            .collect()
    }
}

impl Drop for Postgres {
    fn drop(&mut self) {
        let _ = self
            .command("pg_ctl")
            .args(["-D"])
            .arg(self.dir.path().join("data"))
            .args(["-m", "immediate", "-w", "stop"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status();
    }
}
