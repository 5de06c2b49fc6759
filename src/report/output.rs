//! Atomic output folders: a command's files appear all together or not at all.
//!
//! Files are written into a hidden staging folder next to the target (same parent, so the final
//! rename stays on one file system). [`OutputDir::commit`] moves any previous folder aside,
//! renames the staging folder into place and only then deletes the old one; if the rename fails
//! the old folder is put back. Dropping an uncommitted [`OutputDir`] (an error, a panic) removes
//! the staging folder, so an interrupted or failed run leaves the previous results intact.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// A staging folder that becomes the output folder on commit.
#[derive(Debug)]
pub struct OutputDir {
    target: PathBuf,
    staging: PathBuf,
    committed: bool,
}

impl OutputDir {
    /// Creates the staging folder for `target` (creating the parent folders as needed).
    pub fn create(target: &Path) -> Result<OutputDir> {
        let name = target
            .file_name()
            .ok_or_else(|| Error::io(target, std::io::Error::other("an output folder needs a name")))?
            .to_string_lossy()
            .into_owned();
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        // A file where a folder must be: say so instead of the system's "File exists".
        if let Some(blocker) = parent.ancestors().find(|a| a.exists() && !a.as_os_str().is_empty()) {
            if !blocker.is_dir() {
                return Err(Error::io(
                    blocker,
                    std::io::Error::other(format!(
                        "is a file, so the output folder {} cannot be created there",
                        target.display()
                    )),
                ));
            }
        }
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        if target.exists() && !target.is_dir() {
            return Err(Error::io(target, std::io::Error::other("exists and is not a folder")));
        }
        let staging = parent.join(format!(".{name}.springfit-tmp-{}", std::process::id()));
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        std::fs::create_dir(&staging).map_err(|e| Error::io(&parent, e))?;
        Ok(OutputDir { target: target.to_path_buf(), staging, committed: false })
    }

    /// Where a file named `name` is staged (for writers that create files themselves).
    pub fn path(&self, name: &str) -> PathBuf {
        self.staging.join(name)
    }

    /// The final folder.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Writes a file into the staging folder.
    pub fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> Result<()> {
        let p = self.path(name);
        std::fs::write(&p, bytes).map_err(|e| Error::io(self.target.join(name), e))
    }

    /// Copies the files of the previous folder (if any) whose names `keep` accepts into the
    /// staging folder, so a partial rerun (one scenario of several) replaces only its own files.
    pub fn keep_previous(&self, keep: impl Fn(&str) -> bool) -> Result<()> {
        let Ok(entries) = std::fs::read_dir(&self.target) else { return Ok(()) };
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if e.path().is_file() && keep(&name) {
                std::fs::copy(e.path(), self.path(&name)).map_err(|err| Error::io(e.path(), err))?;
            }
        }
        Ok(())
    }

    /// Moves the staged files into place, replacing any previous folder.
    pub fn commit(mut self) -> Result<PathBuf> {
        let backup = self.staging.with_file_name(format!(
            ".{}.springfit-old-{}",
            self.target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
            std::process::id()
        ));
        let had_old = self.target.exists();
        if had_old {
            if backup.exists() {
                std::fs::remove_dir_all(&backup).map_err(|e| Error::io(&backup, e))?;
            }
            std::fs::rename(&self.target, &backup).map_err(|e| Error::io(&self.target, e))?;
        }
        if let Err(e) = std::fs::rename(&self.staging, &self.target) {
            if had_old {
                let _ = std::fs::rename(&backup, &self.target);
            }
            return Err(Error::io(&self.target, e));
        }
        self.committed = true;
        if had_old {
            // The new results are in place; a leftover backup is harmless but tidy up.
            let _ = std::fs::remove_dir_all(&backup);
        }
        Ok(self.target.clone())
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("springfit-output-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn commit_replaces_the_old_folder() {
        let root = scratch("commit");
        let target = root.join("out");
        std::fs::create_dir_all(&target).unwrap();
        std::fs::write(target.join("old.txt"), "old").unwrap();
        let out = OutputDir::create(&target).unwrap();
        out.write("new.txt", "new").unwrap();
        assert!(!target.join("new.txt").exists(), "nothing visible before commit");
        out.commit().unwrap();
        assert_eq!(std::fs::read_to_string(target.join("new.txt")).unwrap(), "new");
        assert!(!target.join("old.txt").exists());
        let leftovers: Vec<_> = std::fs::read_dir(&root).unwrap().flatten().map(|e| e.file_name()).collect();
        assert_eq!(leftovers.len(), 1, "{leftovers:?}");
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn a_failed_run_leaves_the_previous_results() {
        let root = scratch("fail");
        let target = root.join("out");
        std::fs::create_dir_all(&target).unwrap();
        std::fs::write(target.join("bom.csv"), "previous").unwrap();
        {
            let out = OutputDir::create(&target).unwrap();
            out.write("bom.csv", "half").unwrap();
            // Dropped without commit: the run failed.
        }
        assert_eq!(std::fs::read_to_string(target.join("bom.csv")).unwrap(), "previous");
        assert_eq!(std::fs::read_dir(&root).unwrap().count(), 1);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn an_unwritable_place_names_the_path() {
        let root = scratch("unwritable");
        let file = root.join("plain-file");
        std::fs::write(&file, "x").unwrap();
        let err = OutputDir::create(&file.join("out")).unwrap_err().to_string();
        assert!(err.contains("plain-file"), "{err}");
        let err = OutputDir::create(&file).unwrap_err().to_string();
        assert!(err.contains("not a folder"), "{err}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
