//! Errors and warnings of the config reader; each points at the text it is about.

use std::path::PathBuf;

use crate::span::Span;

/// Why a config could not be read. Every variant that has a place in the input carries its [`Span`].
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{}: cannot read config file: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    #[error("{}:{line}:{column}: config file is not valid UTF-8", path.display())]
    NotUtf8 {
        path: PathBuf,
        line: usize,
        column: usize,
    },

    #[error("{span}: {message}")]
    Syntax { span: Box<Span>, message: String },

    #[error("{span}: include file '{pattern}' does not exist")]
    IncludeNotFound { span: Box<Span>, pattern: String },

    #[error("{span}: invalid include pattern '{pattern}': {message}")]
    IncludePattern {
        span: Box<Span>,
        pattern: String,
        message: String,
    },

    /// An include beyond what a config may pull in (too deep, too many files, too large, not a regular file).
    #[error("{span}: {message}")]
    IncludeRefused { span: Box<Span>, message: String },

    #[error("{span}: recursive include: {}", chain_text(chain))]
    IncludeCycle {
        span: Box<Span>,
        chain: Vec<PathBuf>,
    },

    #[error("{}: missing section [{section}] ({reason})", path.display())]
    MissingSection {
        path: PathBuf,
        section: String,
        reason: String,
    },

    #[error("{span}: option '{key}' in section [{section}] is required")]
    MissingKey {
        /// The section header.
        span: Box<Span>,
        section: String,
        key: String,
    },

    #[error("{span}: option '{key}' in section [{section}]: {message}")]
    InvalidValue {
        span: Box<Span>,
        section: String,
        key: String,
        message: String,
    },

    #[error(
        "{span}: unsupported kinematics '{name}' (supported: cartesian, polar, scara, fivebar, jointspace_polar, jointspace_scara, jointspace_fivebar)"
    )]
    UnsupportedKinematics { span: Box<Span>, name: String },

    #[error("{span}: section [{section}]: {message}")]
    InvalidSection {
        /// The section header.
        span: Box<Span>,
        section: String,
        message: String,
    },
}

impl ConfigError {
    /// Where in the input the problem is, if it has a place.
    pub fn span(&self) -> Option<&Span> {
        match self {
            ConfigError::Io { .. }
            | ConfigError::NotUtf8 { .. }
            | ConfigError::MissingSection { .. } => None,
            ConfigError::Syntax { span, .. }
            | ConfigError::IncludeNotFound { span, .. }
            | ConfigError::IncludePattern { span, .. }
            | ConfigError::IncludeCycle { span, .. }
            | ConfigError::IncludeRefused { span, .. }
            | ConfigError::MissingKey { span, .. }
            | ConfigError::InvalidValue { span, .. }
            | ConfigError::UnsupportedKinematics { span, .. }
            | ConfigError::InvalidSection { span, .. } => Some(span.as_ref()),
        }
    }
}

fn chain_text(chain: &[PathBuf]) -> String {
    chain
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(" -> ")
}

/// Something worth telling the user that does not stop the config from loading.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigWarning {
    pub span: Option<Span>,
    pub message: String,
}

impl std::fmt::Display for ConfigWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.span {
            Some(span) => write!(f, "{span}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}
