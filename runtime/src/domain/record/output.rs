//! A run's output folder, made and checked before the run starts, and taken away again if
//! the run never started (a HIL plant whose controller never came, or that was interrupted
//! while waiting): a failed start leaves nothing half-written behind.

use std::path::{Path, PathBuf};

/// Why a run's output folder cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The folder (or a missing parent) cannot be made.
    #[error("creating {}", path.display())]
    Create {
        /// The folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// No file can be written in the folder.
    #[error("{} is not writable", path.display())]
    NotWritable {
        /// The folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
}

/// The output folder of a run that has not started yet.
#[derive(Debug)]
pub struct OutputDir {
    path: PathBuf,
    /// The outermost folder this made (`None`: the folder existed).
    made: Option<PathBuf>,
}

impl OutputDir {
    /// Makes `path` (and missing parents) and checks that a file can be written in it.
    ///
    /// # Errors
    /// The folder cannot be made, or is not writable.
    pub fn prepare(path: &Path) -> Result<Self, OutputError> {
        let mut made = None;
        let mut p = path;
        while !p.as_os_str().is_empty() && !p.exists() {
            made = Some(p.to_path_buf());
            match p.parent() {
                Some(up) => p = up,
                None => break,
            }
        }
        std::fs::create_dir_all(path)
            .map_err(|source| OutputError::Create { path: path.to_path_buf(), source })?;
        let probe = path.join(".companion-write-test");
        let dir = Self { path: path.to_path_buf(), made };
        if let Err(source) = std::fs::write(&probe, b"") {
            dir.discard();
            return Err(OutputError::NotWritable { path: path.to_path_buf(), source });
        }
        let _ = std::fs::remove_file(&probe);
        Ok(dir)
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The run never started: removes the folders this made, if they are still empty.
    pub fn discard(self) {
        let Some(top) = self.made else { return };
        let mut p = self.path.as_path();
        loop {
            if std::fs::remove_dir(p).is_err() || p == top {
                return;
            }
            match p.parent() {
                Some(up) => p = up,
                None => return,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_made_for_a_run_that_never_started_is_taken_away() {
        let base = std::env::temp_dir().join(format!("companion-output-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        std::fs::create_dir_all(&base).unwrap();
        let deep = base.join("a/b/c");
        let d = OutputDir::prepare(&deep).unwrap();
        assert!(deep.is_dir());
        d.discard();
        assert!(!base.join("a").exists(), "every folder it made is gone");
        assert!(base.exists(), "the folder that existed stays");
        // A folder that existed stays, and so does a made one that has files in it.
        let d = OutputDir::prepare(&base).unwrap();
        d.discard();
        assert!(base.exists());
        let d = OutputDir::prepare(&deep).unwrap();
        std::fs::write(deep.join("x"), "1").unwrap();
        d.discard();
        assert!(deep.join("x").exists());
        std::fs::remove_dir_all(&base).unwrap();
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn an_unwritable_folder_is_an_error() {
        let e = OutputDir::prepare(Path::new("/proc/companion-cannot-be-here")).unwrap_err();
        assert!(format!("{e:#}").contains("/proc/companion-cannot-be-here"), "{e:#}");
    }
}
