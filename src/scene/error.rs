//! Errors of scene import: every problem found, each with its place in the file.
//!
//! A [`SceneError`] is an operating error (bad input), never a programmer error: the CLI maps it to
//! exit code 2 and the service to a 4xx with its message.

use std::fmt;

/// One problem with the input, with where it is (`mesh 0 primitive 1 triangle 17`, `buffer 2`...).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    pub place: String,
    pub message: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.place.is_empty() {
            write!(f, "{}", self.message)
        } else {
            write!(f, "{}: {}", self.place, self.message)
        }
    }
}

/// Why a scene could not be loaded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SceneError {
    /// The bytes are not a readable glTF/GLB (syntax, truncation, wrong magic).
    #[error("not a readable glTF or GLB file: {0}")]
    Unreadable(String),
    /// The file parses but its content is invalid; every problem found is listed.
    #[error("{}", format_problems(.0))]
    Invalid(Vec<Problem>),
    /// The scene is valid but there is nothing to solve or it is over a limit.
    #[error("{0}")]
    Unsolvable(String),
    /// An external file could not be read (CLI) or is not allowed (HTTP).
    #[error("{0}")]
    External(String),
}

/// At most this many problems are spelled out in a message; the rest are counted.
const MAX_PROBLEMS_IN_MESSAGE: usize = 20;

fn format_problems(problems: &[Problem]) -> String {
    let mut s = format!("invalid scene ({} problem(s)): ", problems.len());
    for (i, p) in problems.iter().take(MAX_PROBLEMS_IN_MESSAGE).enumerate() {
        if i > 0 {
            s.push_str("; ");
        }
        s.push_str(&p.to_string());
    }
    if problems.len() > MAX_PROBLEMS_IN_MESSAGE {
        s.push_str(&format!(
            "; and {} more",
            problems.len() - MAX_PROBLEMS_IN_MESSAGE
        ));
    }
    s
}

impl SceneError {
    /// Stable snake_case code for the HTTP error body.
    pub fn code(&self) -> &'static str {
        match self {
            SceneError::Unreadable(_) => "unreadable_scene",
            SceneError::Invalid(_) => "invalid_scene",
            SceneError::Unsolvable(_) => "unsolvable_scene",
            SceneError::External(_) => "external_reference",
        }
    }
}
