//! The one error type of the core. Every variant names the offending argument so that the bindings
//! can turn it into a `ValueError` that tells the user exactly what to fix.

use std::fmt;

/// An error raised by a core algorithm.
#[derive(Debug, Clone, PartialEq)]
pub enum CoreError {
    /// An argument has a value the algorithm cannot work with.
    InvalidArgument {
        /// Name of the argument as the public API spells it.
        name: &'static str,
        /// What was expected and what was given.
        message: String,
    },
    /// The inputs are valid one by one but together describe a problem with no defined answer.
    Unsolvable(String),
}

impl CoreError {
    /// Shorthand for [`CoreError::InvalidArgument`].
    pub fn invalid(name: &'static str, message: impl Into<String>) -> Self {
        CoreError::InvalidArgument {
            name,
            message: message.into(),
        }
    }
}

impl fmt::Display for CoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CoreError::InvalidArgument { name, message } => write!(f, "{name}: {message}"),
            CoreError::Unsolvable(message) => write!(f, "{message}"),
        }
    }
}

impl std::error::Error for CoreError {}

/// Result alias used across the core.
pub type Result<T> = std::result::Result<T, CoreError>;
