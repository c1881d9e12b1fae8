//! Printing to stdout that ends `mpm` quietly when the reader has gone (`mpm schema | head`)
//! instead of panicking as `println!` does. SIGPIPE stays ignored (Rust's default), so a
//! client that disconnects never kills `mpm serve`; only these writes notice the closed pipe.

use std::io::Write;

/// Exit code of `mpm` when its stdout was closed by the reader: the code a shell shows for a
/// program ended by SIGPIPE (128 + 13), so pipelines see what they see for `cat`.
pub(crate) const CLOSED_EXIT_CODE: u8 = 141;

/// Stdout was closed by its reader: nothing more can be printed, and `mpm` ends quietly.
#[derive(Debug)]
pub(crate) struct StdoutClosed;

impl std::fmt::Display for StdoutClosed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("stdout was closed by its reader")
    }
}

impl std::error::Error for StdoutClosed {}

/// Writes `args` to stdout and flushes it: a closed pipe becomes [`StdoutClosed`], any other
/// failure an error that names stdout.
pub(crate) fn write(args: std::fmt::Arguments<'_>) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_fmt(args).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(StdoutClosed.into()),
        Err(e) => Err(anyhow::Error::new(e).context("writing to stdout")),
    }
}

/// Whether `error` is stdout having been closed by its reader.
pub(crate) fn is_closed(error: &anyhow::Error) -> bool {
    error.chain().any(|e| e.is::<StdoutClosed>())
}

/// `print!` that returns `anyhow::Result<()>` (see [`write`]) instead of panicking.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::stdout::write(format_args!($($arg)*))
    };
}

/// `println!` that returns `anyhow::Result<()>` (see [`write`]) instead of panicking.
macro_rules! outln {
    () => {
        $crate::stdout::write(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::stdout::write(format_args!("{}\n", format_args!($($arg)*)))
    };
}

pub(crate) use {out, outln};
