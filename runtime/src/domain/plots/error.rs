//! Why a figure or its page could not be written ([`PlotError`]), for every figure of the
//! runtime (a run's, the latency figures, an exploration's, a tuning's).

use std::path::PathBuf;

/// Why a figure or its page could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Drawing a figure failed: what was being done (`plotting`, `drawing`) and the drawing
    /// library's words.
    #[error("{what}: {detail}")]
    Draw {
        /// `plotting` (a run's figures) or `drawing` (the latency figures).
        what: &'static str,
        /// The drawing library's error, as it prints it for debugging.
        detail: String,
    },
    /// The figures' folder cannot be made.
    #[error("creating {}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// `index.html` cannot be written.
    #[error("writing index.html")]
    Index(#[source] std::io::Error),
    /// A figure file cannot be written.
    #[error("writing {}", path.display())]
    Figure {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

impl PlotError {
    /// A drawing error of a run's figures (`plotting: …`).
    pub fn plotting<E: std::fmt::Debug>(e: E) -> Self {
        Self::Draw { what: "plotting", detail: format!("{e:?}") }
    }
}
