//! How `mpm` exits: the status table of the README, shared by every command.

/// How `mpm` exits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExitStatus {
    /// Done.
    Success,
    /// An operational failure (files, store).
    Failure,
    /// Bad input: an invalid scene or option; nothing was written.
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
