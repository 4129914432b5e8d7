//! The outcome of a command-line tool: every `ickon` subcommand returns
//! `Result<(), CommandError>`, and the `ickon` binary alone turns it into
//! an exit code, so that scripts can tell a mistake in what they passed
//! from a failure while running.

/// Why a subcommand did not succeed.
#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    /// The input was bad (a flag, a site file, a data file): exit code 2.
    #[error("{0}")]
    BadInput(String),
    /// Something failed while running (a node died, nobody answered, a
    /// file could not be written): exit code 1.
    #[error("{0}")]
    Failure(String),
}

impl From<crate::NodeError> for CommandError {
    /// A node's invalid configuration is bad input; anything else stopped it.
    fn from(e: crate::NodeError) -> Self {
        match e {
            crate::NodeError::Config { .. } => Self::BadInput(e.to_string()),
            _ => Self::Failure(e.to_string()),
        }
    }
}

impl CommandError {
    /// Exit code for bad input: a broken site file, a malformed data file, bad flags.
    pub const EXIT_BAD_INPUT: u8 = 2;
    /// Exit code for a failure at run time (a child died, nobody answered).
    pub const EXIT_FAILURE: u8 = 1;

    /// Bad input, with the text the user is shown.
    pub fn bad_input(text: impl Into<String>) -> Self {
        Self::BadInput(text.into())
    }

    /// A failure at run time, with the text the user is shown.
    pub fn failure(text: impl Into<String>) -> Self {
        Self::Failure(text.into())
    }

    /// The same outcome with `context` before its text (`--secure: ...`).
    pub fn context(self, context: &str) -> Self {
        match self {
            Self::BadInput(text) => Self::BadInput(format!("{context}: {text}")),
            Self::Failure(text) => Self::Failure(format!("{context}: {text}")),
        }
    }

    /// The process exit code this outcome is reported with.
    pub fn exit_code(&self) -> u8 {
        match self {
            Self::BadInput(_) => Self::EXIT_BAD_INPUT,
            Self::Failure(_) => Self::EXIT_FAILURE,
        }
    }
}
