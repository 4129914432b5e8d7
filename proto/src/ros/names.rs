//! ROS 2 names: validation and resolution of a topic name against a
//! namespace, as `rcl` does for the plain cases (absolute `/a/b` and
//! relative `a/b`; private `~` names and substitutions are not supported).

use thiserror::Error;

/// Why a ROS name or namespace is not usable.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RosNameError {
    /// An empty name.
    #[error("empty ROS name")]
    Empty,
    /// A character other than letters, digits, `_` and `/`.
    #[error("ROS name {0:?} has a character other than letters, digits, '_' and '/'")]
    BadCharacter(String),
    /// `//`, a trailing `/`, or a token starting with a digit.
    #[error(
        "ROS name {0:?} is malformed (empty token, trailing '/' or a token starting with a digit)"
    )]
    Malformed(String),
    /// A `~` or `{}` name, which this implementation does not resolve.
    #[error("ROS name {0:?}: private names and substitutions are not supported")]
    Unsupported(String),
    /// A namespace that does not start with `/`.
    #[error("ROS namespace {0:?} must start with '/'")]
    RelativeNamespace(String),
    /// A type name not of the form `pkg/msg/Name`.
    #[error("ROS type name {0:?} is not of the form pkg/msg/Name")]
    BadTypeName(String),
}

fn check_tokens(whole: &str, body: &str) -> Result<(), RosNameError> {
    if body.is_empty() {
        return Ok(());
    }
    for token in body.split('/') {
        let Some(first) = token.chars().next() else {
            return Err(RosNameError::Malformed(whole.to_string()));
        };
        if first.is_ascii_digit() {
            return Err(RosNameError::Malformed(whole.to_string()));
        }
    }
    Ok(())
}

fn check_chars(name: &str) -> Result<(), RosNameError> {
    if name.contains(['~', '{', '}']) {
        return Err(RosNameError::Unsupported(name.to_string()));
    }
    if !name
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/')
    {
        return Err(RosNameError::BadCharacter(name.to_string()));
    }
    Ok(())
}

/// Checks a namespace: `/` or `/a/b` (absolute, no trailing `/`).
pub fn validate_namespace(namespace: &str) -> Result<(), RosNameError> {
    if namespace.is_empty() {
        return Err(RosNameError::Empty);
    }
    check_chars(namespace)?;
    let Some(body) = namespace.strip_prefix('/') else {
        return Err(RosNameError::RelativeNamespace(namespace.to_string()));
    };
    check_tokens(namespace, body)
}

/// The absolute name of topic `name` in `namespace`: an absolute name
/// (`/tf`) stays as it is, a relative one (`pose`, `ickon/fix`) is put
/// under the namespace (`/r1/pose`).
pub fn resolve_topic(namespace: &str, name: &str) -> Result<String, RosNameError> {
    validate_namespace(namespace)?;
    if name.is_empty() {
        return Err(RosNameError::Empty);
    }
    check_chars(name)?;
    let resolved = if name.starts_with('/') {
        name.to_string()
    } else if namespace == "/" {
        format!("/{name}")
    } else {
        format!("{namespace}/{name}")
    };
    let body = &resolved[1..];
    if body.is_empty() {
        return Err(RosNameError::Malformed(name.to_string()));
    }
    check_tokens(name, body)?;
    Ok(resolved)
}

/// The DDS type name rmw_zenoh puts in keys: `nav_msgs/msg/Odometry` is
/// `nav_msgs::msg::dds_::Odometry_`.
pub fn dds_type_name(type_name: &str) -> Result<String, RosNameError> {
    let parts: Vec<&str> = type_name.split('/').collect();
    match parts.as_slice() {
        [pkg, kind, name]
            if !pkg.is_empty()
                && !kind.is_empty()
                && !name.is_empty()
                && type_name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/') =>
        {
            Ok(format!("{pkg}::{kind}::dds_::{name}_"))
        }
        _ => Err(RosNameError::BadTypeName(type_name.to_string())),
    }
}
