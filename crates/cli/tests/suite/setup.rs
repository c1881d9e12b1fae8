//! The README's shell commands and `.ci/run`, checked against the repository, so that what a
//! new user copies works as written: the set-up section installs the package that has the
//! `mpm` binary, every `mpm` line parses, and CI fetches every crate before building.

use clap::Parser;
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The commands of the README's ```sh blocks (of one section when `section` is given), with
/// comments and a trailing `&` removed and lines continued with `\` joined.
fn shell_lines(section: Option<&str>) -> Vec<String> {
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let mut current = String::new();
    let mut inside = false;
    let mut lines = Vec::new();
    let mut continued = String::new();
    for line in readme.lines() {
        if inside && let Some(head) = line.trim_end().strip_suffix('\\') {
            continued.push_str(head);
            continued.push(' ');
            continue;
        }
        let joined = std::mem::take(&mut continued) + line;
        let line = joined.as_str();
        if let Some(title) = line.strip_prefix("## ") {
            current = title.to_string();
        }
        if line.starts_with("```") {
            inside = line == "```sh";
            continue;
        }
        if inside && section.is_none_or(|s| s == current) {
            let command = line.split(" #").next().unwrap_or("").trim();
            let command = command.strip_suffix('&').unwrap_or(command).trim();
            if !command.is_empty() {
                lines.push(command.to_string());
            }
        }
    }
    lines
}

/// Splits a shell line into words: whitespace separates, quotes group; no expansion.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    let mut quote = None;
    let mut started = false;
    for c in line.chars() {
        match (quote, c) {
            (None, '"' | '\'') => {
                quote = Some(c);
                started = true;
            }
            (Some(q), c) if c == q => quote = None,
            (None, c) if c.is_whitespace() => {
                if started {
                    out.push(std::mem::take(&mut word));
                    started = false;
                }
            }
            (_, c) => {
                word.push(c);
                started = true;
            }
        }
    }
    if started {
        out.push(word);
    }
    out
}

#[test]
fn the_set_up_section_installs_mpm_then_runs_an_example() {
    let lines = shell_lines(Some("Set up and run"));
    let install = lines
        .iter()
        .position(|l| l.starts_with("cargo install "))
        .expect("the set-up section puts `mpm` on the PATH with `cargo install`");
    let w = words(&lines[install]);
    assert!(w.iter().any(|x| x == "--locked"), "{w:?}: use Cargo.lock");
    let at = w.iter().position(|x| x == "--path").expect("--path") + 1;
    let manifest = std::fs::read_to_string(repo().join(&w[at]).join("Cargo.toml")).unwrap();
    assert!(
        manifest.contains("[[bin]]\nname = \"mpm\""),
        "{} has no `mpm` binary",
        w[at]
    );
    let runs: Vec<&String> = lines[install + 1..]
        .iter()
        .filter(|l| l.starts_with("mpm "))
        .collect();
    assert!(
        !runs.is_empty(),
        "the set-up section runs `mpm` after installing it"
    );
    for line in runs {
        for arg in words(line).iter().filter(|a| a.ends_with(".json")) {
            assert!(repo().join(arg).is_file(), "{line}: no file {arg}");
        }
    }
}

#[test]
fn every_mpm_command_of_the_readme_parses() {
    let lines: Vec<String> = shell_lines(None)
        .into_iter()
        .filter(|l| l.starts_with("mpm "))
        .collect();
    assert!(lines.len() >= 10, "{lines:?}");
    for line in &lines {
        if let Err(e) = mpm_cli::Cli::try_parse_from(words(line)) {
            panic!("README: `{line}` does not parse:\n{e}");
        }
        for arg in words(line).iter().filter(|a| a.starts_with("examples/")) {
            assert!(repo().join(arg).is_file(), "{line}: no file {arg}");
        }
    }
}

#[test]
fn ci_fetches_every_crate_before_it_builds() {
    let script = std::fs::read_to_string(repo().join(".ci/run")).unwrap();
    let cargo: Vec<&str> = script
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("cargo "))
        .collect();
    assert_eq!(
        cargo.first().copied(),
        Some("cargo fetch --locked"),
        "{cargo:?}"
    );
    assert!(cargo.len() >= 4, "{cargo:?}");
}
