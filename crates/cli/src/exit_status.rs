//! How `mpm` exits: the status table of the README, and the error marker that makes a
//! failure "invalid input" (2) rather than an operational failure (1).

/// How `mpm` exits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExitStatus {
    /// Done.
    Success,
    /// An operational failure (files, I/O, server unreachable).
    Failure,
    /// Bad input: an invalid scene or option, or a request the server refused; nothing was
    /// written.
    InvalidInput,
    /// The run stopped on a check (NaN, det F <= 0, ...); frames written so far are kept.
    Stopped,
}

impl From<ExitStatus> for std::process::ExitCode {
    fn from(s: ExitStatus) -> Self {
        std::process::ExitCode::from(match s {
            ExitStatus::Success => 0,
            ExitStatus::Failure => 1,
            ExitStatus::InvalidInput => 2,
            ExitStatus::Stopped => 3,
        })
    }
}

impl ExitStatus {
    /// The status of a command that ended with `error`: invalid input (2) when an
    /// [`InputError`] is anywhere in its chain, otherwise an operational failure (1).
    pub(crate) fn of_error(error: &anyhow::Error) -> Self {
        if error.chain().any(|e| e.is::<InputError>()) {
            ExitStatus::InvalidInput
        } else {
            ExitStatus::Failure
        }
    }
}

/// A failure caused by what the user gave rather than by the machine: an option value, a
/// scene that is not JSON, a request the server refused (4xx). `mpm` exits 2 for it, not 1.
#[derive(Debug)]
pub(crate) struct InputError(pub String);

impl std::fmt::Display for InputError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for InputError {}

/// An [`InputError`] as an `anyhow::Error`, with a message formatted as by `format!`.
macro_rules! input_error {
    ($($arg:tt)*) => {
        anyhow::Error::new($crate::exit_status::InputError(format!($($arg)*)))
    };
}
pub(crate) use input_error;
