//! The one error type of the nodes' Zenoh edges: what can stop a node from
//! starting or running, with a clear text. Binaries print it and exit 1
//! (2 for an invalid configuration: [`crate::run_node`]).

/// Why a node could not start or go on.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// Zenoh refused an operation (open a session, declare, query).
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// A Zenoh configuration file or setting is invalid.
    #[error("Zenoh config {what}: {reason}")]
    Config {
        /// The file or the setting.
        what: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A message could not be encoded.
    #[error(transparent)]
    Encode(#[from] ickon_proto::EncodeError),
    /// A key could not be built (an invalid site, cell or robot id).
    #[error(transparent)]
    Key(#[from] ickon_proto::keys::KeyError),
    /// The site the node was given or fetched is invalid.
    #[error(transparent)]
    Site(#[from] ickon_proto::site::SiteError),
    /// The node cannot do what it was asked with this site and these
    /// arguments (an unknown robot, an estimator that cannot be built, ...).
    #[error("{0}")]
    Setup(String),
}

/// Turns a Zenoh error (a boxed error) into a [`NodeError`].
pub fn zerr(e: zenoh::Error) -> NodeError {
    NodeError::Zenoh(e.to_string())
}
