//! Output folders that never lose a user's files: a command's files appear all together or not at
//! all, and springfit only ever replaces or removes files it wrote itself.
//!
//! Every output folder carries a manifest, [`MANIFEST`], naming the command that wrote it and the
//! files it wrote. A command writes
//!
//! - into a folder that does not exist yet (it is created whole: staged, then renamed into place);
//! - into an existing empty folder, or one whose manifest names the same command: the new files
//!   are swapped in one by one, the files of the previous run's manifest that the new run no
//!   longer writes are removed, and every other file or subfolder is left as it is;
//! - never into any other existing folder (a folder with files but no manifest, or the output
//!   folder of another command): that is refused, before any work, with a message saying what to
//!   do.
//!
//! The manifest also records what springfit wrote into each file (its size and a 64-bit FNV-1a
//! hash of its bytes), so a file a user edited since (a `bom.csv` with `measured_stiffness`
//! filled in) is told apart from springfit's own: a run that would replace or remove it is
//! refused before any work, naming the file, unless the caller says the edits may go
//! ([`Edits::Overwrite`]). A command announces the names it may write ([`Plan`]) before it starts,
//! so a file of the user's that sits where the run would write is refused before any work too,
//! not after it.
//!
//! Files are first written into a hidden staging folder next to the target (same parent, so the
//! renames stay on one file system). On commit the previous files are moved into a hidden backup
//! folder, the new ones moved in, and only then is the backup deleted; if a step fails, the new
//! files are taken out again and the previous ones put back. Dropping an uncommitted
//! [`OutputDir`] (an error, a panic) removes the staging folder, so a failed run leaves the
//! previous results intact.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The manifest's file name inside an output folder.
pub const MANIFEST: &str = ".springfit-manifest.json";

/// What an output folder's manifest records: who wrote the folder and which files.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// The springfit version that wrote the folder.
    pub springfit: String,
    /// The command that wrote it (`fit`, `simulate`, …); only this command may write there again.
    pub command: String,
    /// The files springfit wrote, relative to the folder, `/`-separated, sorted.
    pub files: Vec<String>,
    /// Subfolders springfit created for its files (removed again once empty).
    #[serde(default)]
    pub folders: Vec<String>,
    /// What springfit wrote into each file, so a file edited since is recognised. Manifests of
    /// springfit versions before this field have none: their files count as edited when they are
    /// newer than the manifest.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub stamps: BTreeMap<String, Stamp>,
    /// The design whose results the folder holds, for commands that run one design. Another
    /// design may not replace them (see [`Plan::for_design`]). Manifests of springfit versions
    /// before this field, and of commands on several designs, have none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub design: Option<DesignRecord>,
}

/// Which design a folder's results are of: its file and a fingerprint of the text it was read
/// from, so a copy with one key changed is told apart from the design it was copied from, while
/// the same file edited and run again (the usual way to iterate) is the same design.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesignRecord {
    /// The design file, as an absolute path where it could be resolved.
    pub path: String,
    /// FNV-1a (64-bit) of the design's text, 16 hexadecimal digits (as [`crate::design::Design::fingerprint`]).
    pub fnv1a64: String,
}

impl DesignRecord {
    /// The record of `design`: its path made absolute, and the fingerprint of its text.
    pub fn of(design: &crate::design::Design) -> DesignRecord {
        let path = std::fs::canonicalize(&design.path).unwrap_or_else(|_| design.path.clone());
        DesignRecord { path: path.display().to_string(), fnv1a64: design.fingerprint.clone() }
    }

    /// Whether a run of `self` may replace results of `other`: the same file (edited or not), or
    /// another file with the same text (a copy or a renamed file).
    fn same_design(&self, other: &DesignRecord) -> bool {
        self.path == other.path || self.fnv1a64 == other.fnv1a64
    }
}

/// What springfit wrote into one file: enough to tell whether anyone changed it since.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stamp {
    /// Size in bytes.
    pub bytes: u64,
    /// FNV-1a (64-bit) of the bytes, 16 hexadecimal digits. Not a cryptographic hash: it guards
    /// against edits, not against someone forging a file.
    pub fnv1a64: String,
}

impl Stamp {
    /// The stamp of `bytes`.
    pub fn of(bytes: &[u8]) -> Stamp {
        Stamp { bytes: bytes.len() as u64, fnv1a64: crate::input::fingerprint(bytes) }
    }

    fn of_file(path: &Path) -> Result<Stamp> {
        std::fs::read(path).map(|b| Stamp::of(&b)).map_err(|e| Error::io(path, e))
    }
}

/// What to do with a file springfit wrote that has been changed since.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Edits {
    /// Refuse the run before any work, naming the edited files (the default).
    #[default]
    Refuse,
    /// Replace or remove edited files like any other file of the previous run.
    Overwrite,
}

/// What a command is about to write into an output folder, known before it does any work: its
/// name, the file names it may write (exact, or with `*` standing for any run of characters,
/// `/` included) and what to do with files a user edited.
#[derive(Debug, Clone)]
pub struct Plan {
    command: String,
    patterns: Vec<String>,
    edits: Edits,
    design: Option<DesignRecord>,
}

impl Plan {
    /// The plan of `command` writing files whose names match `patterns`.
    pub fn new<S: Into<String>>(command: &str, patterns: impl IntoIterator<Item = S>) -> Plan {
        Plan {
            command: command.to_string(),
            patterns: patterns.into_iter().map(Into::into).collect(),
            edits: Edits::Refuse,
            design: None,
        }
    }

    /// The same plan for a run of `design`: the folder's manifest records the design, and a run
    /// of another design (another file with other contents) is refused before any work, so a
    /// copy of a design that kept its `name` does not replace the original's results.
    pub fn for_design(mut self, design: &crate::design::Design) -> Plan {
        self.design = Some(DesignRecord::of(design));
        self
    }

    /// The same plan with another policy for edited files.
    pub fn with_edits(mut self, edits: Edits) -> Plan {
        self.edits = edits;
        self
    }

    /// The command (`fit`, `simulate`, …).
    pub fn command(&self) -> &str {
        &self.command
    }

    /// Whether the run may write a file of this name.
    pub fn covers(&self, name: &str) -> bool {
        self.patterns.iter().any(|p| glob(p.as_bytes(), name.as_bytes()))
    }
}

/// `*` matches any run of bytes; everything else matches itself.
fn glob(pattern: &[u8], name: &[u8]) -> bool {
    match pattern.split_first() {
        None => name.is_empty(),
        Some((b'*', rest)) => (0..=name.len()).any(|i| glob(rest, &name[i..])),
        Some((c, rest)) => name.split_first().is_some_and(|(n, tail)| n == c && glob(rest, tail)),
    }
}

impl Manifest {
    fn empty(command: &str) -> Manifest {
        Manifest {
            springfit: env!("CARGO_PKG_VERSION").to_string(),
            command: command.to_string(),
            files: Vec::new(),
            folders: Vec::new(),
            stamps: BTreeMap::new(),
            design: None,
        }
    }

    /// The files of this manifest in `folder` whose contents differ from what springfit wrote
    /// (files that are gone are not edits: nothing of the user's would be lost).
    fn edited(&self, folder: &Path) -> Result<Vec<String>> {
        let written_at = std::fs::metadata(folder.join(MANIFEST)).and_then(|m| m.modified()).ok();
        let mut edited = Vec::new();
        for f in &self.files {
            let path = folder.join(f);
            let Ok(meta) = path.symlink_metadata() else { continue };
            if !meta.is_file() {
                edited.push(f.clone());
                continue;
            }
            let changed = match self.stamps.get(f) {
                Some(stamp) => meta.len() != stamp.bytes || Stamp::of_file(&path)? != *stamp,
                // No record of the contents: newer than the manifest means changed after the run.
                None => match (meta.modified().ok(), written_at) {
                    (Some(m), Some(w)) => m > w,
                    _ => true,
                },
            };
            if changed {
                edited.push(f.clone());
            }
        }
        Ok(edited)
    }

    /// Reads the manifest of `folder`, if it has one.
    pub fn read(folder: &Path) -> Result<Option<Manifest>> {
        let path = folder.join(MANIFEST);
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let m: Manifest = serde_json::from_str(&text).map_err(|e| {
            refusal(
                folder,
                &format!("its springfit manifest {MANIFEST} does not parse ({e}), so springfit cannot tell its own files from others"),
            )
        })?;
        for f in m.files.iter().chain(&m.folders) {
            if !is_plain_relative(f) {
                return Err(refusal(
                    folder,
                    &format!("its springfit manifest {MANIFEST} lists `{f}`, which is not a path inside the folder"),
                ));
            }
        }
        Ok(Some(m))
    }
}

/// A path such as `a.csv` or `plots/a.png`: relative, no `..`, no root.
fn is_plain_relative(p: &str) -> bool {
    !p.is_empty() && Path::new(p).components().all(|c| matches!(c, Component::Normal(_)))
}

/// The error for a folder springfit must not write into, with what to do about it.
fn refusal(folder: &Path, why: &str) -> Error {
    Error::io(
        folder,
        std::io::Error::other(format!(
            "{why}; springfit never replaces files it did not write: choose another --out (a new or empty folder) or remove this folder yourself"
        )),
    )
}

/// What is at the target before a run.
#[derive(Debug)]
enum Previous {
    /// Nothing: the folder is created whole.
    Absent,
    /// An empty folder or a folder of the same command: files are swapped in.
    Managed(Manifest),
}

/// Claims `target` for the run of `plan`: checks that the run may write its outputs there (see
/// the module documentation) and locks the folder against other springfit runs until the claim,
/// or the [`OutputDir`] opened from it, is dropped. Commands call it before any work, so that a
/// refusal costs nothing and a second run into the same folder stops at once instead of
/// replacing the first run's results. It writes nothing but the lock (and the folders above
/// the target, removed again if the run writes nothing).
pub fn check(target: &Path, plan: &Plan) -> Result<Claim> {
    let lock = Lock::take(target, plan.command())?;
    inspect(target, plan)?;
    Ok(Claim { target: target.to_path_buf(), plan: plan.clone(), lock })
}

/// An output folder claimed for one run (see [`check`]): checked, and locked against other runs.
#[derive(Debug)]
#[must_use = "the folder is locked only while the claim lives: open it with `Claim::open`"]
pub struct Claim {
    target: PathBuf,
    plan: Plan,
    lock: Lock,
}

impl Claim {
    /// The folder the run writes.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Opens the claimed folder for writing: checks it again (it may have changed during the
    /// run's work) and creates the staging folder the run's files go to.
    pub fn open(self) -> Result<OutputDir> {
        OutputDir::stage(self)
    }
}

/// The lock of an output folder: a file `.<name>.springfit-lock` beside it, held with the
/// operating system's advisory lock (released by the system if the process dies, so a killed
/// run never leaves a folder locked) and removed when the run ends.
#[derive(Debug)]
struct Lock {
    path: PathBuf,
    file: Option<std::fs::File>,
    /// Folders created above the target to hold the lock, removed again when they stay empty.
    created: Vec<PathBuf>,
}

impl Lock {
    fn take(target: &Path, command: &str) -> Result<Lock> {
        let name = target
            .file_name()
            .ok_or_else(|| Error::io(target, std::io::Error::other("an output folder needs a name")))?
            .to_string_lossy()
            .into_owned();
        let parent = parent_of(target);
        placeable(target)?;
        let created: Vec<PathBuf> = parent
            .ancestors()
            .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
            .map(Path::to_path_buf)
            .collect();
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        let mut lock = Lock { path: parent.join(format!(".{name}.springfit-lock")), file: None, created };
        // A run that ends removes its lock file while it still holds it; a run that opened the
        // file just before may then lock a file that is no longer there: it tries again.
        for _ in 0..100 {
            let file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&lock.path)
                .map_err(|e| Error::io(&lock.path, e))?;
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    let holder = std::fs::read_to_string(&lock.path).unwrap_or_default();
                    let holder = holder.trim();
                    return Err(Error::io(
                        target,
                        std::io::Error::other(format!(
                            "another springfit run is writing this folder ({}); two runs into one folder would lose the first one's results: wait until it ends or choose another --out",
                            if holder.is_empty() { "it has just started" } else { holder }
                        )),
                    ));
                }
                // A file system without locks (some network mounts): go on unlocked.
                Err(std::fs::TryLockError::Error(e)) if e.kind() == std::io::ErrorKind::Unsupported => {
                    lock.file = Some(file);
                    return Ok(lock);
                }
                Err(std::fs::TryLockError::Error(e)) => return Err(Error::io(&lock.path, e)),
            }
            if !still_there(&file, &lock.path) {
                continue;
            }
            use std::io::Write;
            let _ = file.set_len(0);
            let _ = write!(&file, "process {}, `springfit {command}`", std::process::id());
            lock.file = Some(file);
            return Ok(lock);
        }
        Err(Error::io(&lock.path, std::io::Error::other("could not take the output folder's lock")))
    }
}

/// Whether the open `file` is still the one at `path` (not removed or replaced since it was opened).
fn still_there(file: &std::fs::File, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (file.metadata(), std::fs::metadata(path)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = file;
        path.exists()
    }
}

impl Drop for Lock {
    fn drop(&mut self) {
        if let Some(file) = self.file.take() {
            // Removed while still held, then released (see `Lock::take`).
            let _ = std::fs::remove_file(&self.path);
            drop(file);
        }
        for d in &self.created {
            let _ = std::fs::remove_dir(d); // fails, as wanted, unless empty
        }
    }
}

fn inspect(target: &Path, plan: &Plan) -> Result<Previous> {
    let command = plan.command();
    placeable(target)?;
    if !target.exists() {
        return Ok(Previous::Absent);
    }
    if !target.is_dir() {
        return Err(Error::io(target, std::io::Error::other("exists and is not a folder")));
    }
    let previous = match Manifest::read(target)? {
        Some(m) if m.command == command => m,
        Some(m) => {
            return Err(refusal(
                target,
                &format!(
                    "this is an output folder of `springfit {}`, and `springfit {command}` does not replace another command's files",
                    m.command
                ),
            ));
        }
        None => {
            let mut entries = std::fs::read_dir(target).map_err(|e| Error::io(target, e))?;
            if entries.next().is_some() {
                return Err(refusal(
                    target,
                    &format!("the folder is not empty and has no springfit manifest ({MANIFEST})"),
                ));
            }
            Manifest::empty(command)
        }
    };
    if let (Some(theirs), Some(ours)) = (&previous.design, &plan.design)
        && !ours.same_design(theirs)
    {
        return Err(Error::io(
            target,
            std::io::Error::other(format!(
                "it holds the results of the design {}, and this run is of {}, another design (another file with other contents, perhaps a copy that kept its `name`); springfit does not replace one design's results with another's: pass --out with a folder for this design (a new one), or remove this folder yourself",
                theirs.path, ours.path
            )),
        ));
    }
    if plan.edits == Edits::Refuse {
        let edited = previous.edited(target)?;
        if !edited.is_empty() {
            return Err(Error::io(
                target,
                std::io::Error::other(format!(
                    "{} changed since `springfit {command}` wrote {} (edited by hand?), and this run would replace or remove {}; springfit does not overwrite your edits: copy {} elsewhere first, choose another --out, or pass --overwrite-edits to let the run replace {}",
                    list(&edited),
                    if edited.len() == 1 { "it" } else { "them" },
                    if edited.len() == 1 { "it" } else { "them" },
                    if edited.len() == 1 { "it" } else { "them" },
                    if edited.len() == 1 { "it" } else { "them" },
                )),
            ));
        }
    }
    let listed: BTreeSet<&str> = previous.files.iter().map(String::as_str).collect();
    let (present, _) = listing(target)?;
    let in_the_way: Vec<String> =
        present.into_iter().filter(|f| !listed.contains(f.as_str()) && plan.covers(f)).collect();
    if let Some(f) = in_the_way.first() {
        return Err(refusal(
            target,
            &format!("it holds `{f}`, which springfit did not write but this run may write; move that file away first"),
        ));
    }
    Ok(Previous::Managed(previous))
}

/// Whether a folder can be made at `target`, explained in words where the system's would puzzle:
/// a file where a folder must be ("File exists"), a link to nothing ("Not a directory"), a place
/// that takes no new folders.
fn placeable(target: &Path) -> Result<()> {
    let parent = parent_of(target);
    if let Some(blocker) = parent.ancestors().find(|a| a.exists() && !a.as_os_str().is_empty())
        && !blocker.is_dir()
    {
        return Err(Error::io(
            blocker,
            std::io::Error::other(format!(
                "is a file, so the output folder {} cannot be created there",
                target.display()
            )),
        ));
    }
    if target.symlink_metadata().is_ok_and(|m| m.file_type().is_symlink()) && !target.exists() {
        let to = std::fs::read_link(target).map(|t| t.display().to_string()).unwrap_or_default();
        return Err(Error::io(
            target,
            std::io::Error::other(format!(
                "is a symbolic link to {to}, which does not exist: choose another --out or remove the link"
            )),
        ));
    }
    writable(target)
}

/// `a`, `a` and `b`, `a`, `b` and `c` (each in backquotes).
fn list(names: &[String]) -> String {
    let q: Vec<String> = names.iter().map(|n| format!("`{n}`")).collect();
    match q.len() {
        0 => String::new(),
        1 => q[0].clone(),
        n => format!("{} and {}", q[..n - 1].join(", "), q[n - 1]),
    }
}

/// Whether the output folder can be made: the nearest existing folder above it takes a new
/// entry (a probe folder, created and removed at once). A place the system refuses, such as
/// `/proc/x` or a read-only mount, is named before any work instead of with the system's words
/// after it.
fn writable(target: &Path) -> Result<()> {
    let parent = parent_of(target);
    let Some(base) = parent.ancestors().find(|a| a.as_os_str().is_empty() || a.is_dir()) else { return Ok(()) };
    let base = if base.as_os_str().is_empty() { Path::new(".") } else { base };
    let probe = base.join(format!(".springfit-probe-{}", std::process::id()));
    match std::fs::create_dir(&probe) {
        Ok(()) => {
            let _ = std::fs::remove_dir(&probe);
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => Err(Error::io(
            target,
            std::io::Error::other(format!(
                "the output folder cannot be created: {} does not take new folders ({e}); choose another --out",
                base.display()
            )),
        )),
    }
}

fn parent_of(target: &Path) -> PathBuf {
    match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A staging folder whose files become the output folder's on commit.
#[derive(Debug)]
pub struct OutputDir {
    target: PathBuf,
    staging: PathBuf,
    plan: Plan,
    previous: Previous,
    /// Files of the previous run copied back by [`OutputDir::keep_previous`]: written, though
    /// not by this run's plan.
    kept: BTreeSet<String>,
    committed: bool,
    /// Held until the folder is committed or dropped; declared last, so it is released after
    /// the staging folder is gone.
    _lock: Lock,
}

impl OutputDir {
    /// Claims `target` for `plan` ([`check`]) and opens it ([`Claim::open`]), for callers that do
    /// no work between the two. Refuses what [`check`] refuses.
    pub fn create(target: &Path, plan: &Plan) -> Result<OutputDir> {
        check(target, plan)?.open()
    }

    fn stage(claim: Claim) -> Result<OutputDir> {
        let Claim { target, plan, lock } = claim;
        let name = target
            .file_name()
            .ok_or_else(|| Error::io(&target, std::io::Error::other("an output folder needs a name")))?
            .to_string_lossy()
            .into_owned();
        let previous = inspect(&target, &plan)?;
        let parent = parent_of(&target);
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        let staging = parent.join(format!(".{name}.springfit-tmp-{}", std::process::id()));
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        std::fs::create_dir(&staging).map_err(|e| Error::io(&parent, e))?;
        Ok(OutputDir { target, staging, plan, previous, kept: BTreeSet::new(), committed: false, _lock: lock })
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
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).map_err(|e| Error::io(self.target.join(name), e))?;
        }
        std::fs::write(&p, bytes).map_err(|e| Error::io(self.target.join(name), e))
    }

    /// Keeps the previous run's files (those its manifest lists) whose names `keep` accepts, so a
    /// partial rerun (one scenario of several) replaces only its own files. Files springfit did
    /// not write are never touched anyway.
    pub fn keep_previous(&mut self, keep: impl Fn(&str) -> bool) -> Result<()> {
        let Previous::Managed(m) = &self.previous else { return Ok(()) };
        for name in &m.files {
            let from = self.target.join(name);
            if from.is_file() && keep(name) {
                let to = self.path(name);
                if let Some(parent) = to.parent() {
                    std::fs::create_dir_all(parent).map_err(|e| Error::io(&to, e))?;
                }
                std::fs::copy(&from, &to).map_err(|err| Error::io(&from, err))?;
                self.kept.insert(name.clone());
            }
        }
        Ok(())
    }

    /// Moves the staged files into place (see the module documentation) and returns the folder.
    pub fn commit(mut self) -> Result<PathBuf> {
        let (files, folders) = listing(&self.staging)?;
        // The refusals before the work relied on the plan: a file outside it is springfit's bug.
        if let Some(f) = files.iter().find(|f| !self.plan.covers(f) && !self.kept.contains(*f)) {
            return Err(Error::io(
                self.target.join(f),
                std::io::Error::other(format!(
                    "`springfit {}` would write this file without having announced it before its work (a bug in springfit: please report it); nothing was written",
                    self.plan.command()
                )),
            ));
        }
        let mut stamps = BTreeMap::new();
        for f in &files {
            stamps.insert(f.clone(), Stamp::of_file(&self.staging.join(f))?);
        }
        let manifest = Manifest {
            springfit: env!("CARGO_PKG_VERSION").to_string(),
            command: self.plan.command().to_string(),
            files,
            folders,
            stamps,
            design: self.plan.design.clone(),
        };
        // Inspect again: the folder may have changed while the command ran.
        match inspect(&self.target, &self.plan)? {
            Previous::Absent => {
                write_manifest(&self.staging, &manifest)?;
                std::fs::rename(&self.staging, &self.target).map_err(|e| Error::io(&self.target, e))?;
            }
            Previous::Managed(old) => {
                swap_in(&self.target, &self.staging, &old, &manifest)?;
                let _ = std::fs::remove_dir_all(&self.staging);
            }
        }
        self.committed = true;
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

/// The files and subfolders under `root` (relative, `/`-separated, sorted), the manifest left out.
fn listing(root: &Path) -> Result<(Vec<String>, Vec<String>)> {
    fn walk(root: &Path, dir: &Path, files: &mut Vec<String>, folders: &mut Vec<String>) -> Result<()> {
        for e in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
            let e = e.map_err(|err| Error::io(dir, err))?;
            let p = e.path();
            let rel = p.strip_prefix(root).unwrap_or(&p);
            let rel = rel.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/");
            // Symbolic links are listed, not followed.
            if e.file_type().map_err(|err| Error::io(&p, err))?.is_dir() {
                folders.push(rel);
                walk(root, &p, files, folders)?;
            } else if rel != MANIFEST {
                files.push(rel);
            }
        }
        Ok(())
    }
    let (mut files, mut folders) = (Vec::new(), Vec::new());
    walk(root, root, &mut files, &mut folders)?;
    files.sort();
    folders.sort();
    Ok((files, folders))
}

/// Writes the manifest into `folder` through a temporary file and a rename, so it is never
/// half-written.
fn write_manifest(folder: &Path, m: &Manifest) -> Result<()> {
    let text =
        serde_json::to_string_pretty(m).map_err(|e| Error::io(folder.join(MANIFEST), std::io::Error::other(e)))?;
    let tmp = folder.join(format!("{MANIFEST}.tmp-{}", std::process::id()));
    std::fs::write(&tmp, text + "\n").map_err(|e| Error::io(folder.join(MANIFEST), e))?;
    std::fs::rename(&tmp, folder.join(MANIFEST)).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(folder.join(MANIFEST), e)
    })
}

/// Swaps the staged files into an existing folder whose previous manifest is `old`.
fn swap_in(target: &Path, staging: &Path, old: &Manifest, new: &Manifest) -> Result<()> {
    let old_files: BTreeSet<&str> = old.files.iter().map(String::as_str).collect();
    // A file of ours would land on a file springfit did not write: refuse rather than lose it.
    for f in &new.files {
        let t = target.join(f);
        if t.symlink_metadata().is_ok() && (!old_files.contains(f.as_str()) || t.is_dir()) {
            return Err(refusal(
                target,
                &format!(
                    "it holds `{f}`, which springfit did not write but would now write; move that file away first"
                ),
            ));
        }
    }
    // First a manifest covering old and new files, so an interruption leaves nothing unlisted.
    let mut union = old.clone();
    union.files = old_files.iter().map(|s| s.to_string()).chain(new.files.iter().cloned()).collect();
    union.files.sort();
    union.files.dedup();
    union.folders.extend(new.folders.iter().cloned());
    union.folders.sort();
    union.folders.dedup();
    // While files are being swapped a listed file may hold the old or the new bytes: the stamps of
    // files about to be replaced are dropped, so an interrupted swap is judged by modification time.
    union.stamps.retain(|f, _| !new.files.contains(f));
    write_manifest(target, &union)?;

    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let backup = parent_of(target).join(format!(".{name}.springfit-old-{}", std::process::id()));
    if backup.exists() {
        std::fs::remove_dir_all(&backup).map_err(|e| Error::io(&backup, e))?;
    }
    std::fs::create_dir(&backup).map_err(|e| Error::io(&backup, e))?;

    let mut moved_out: Vec<&str> = Vec::new();
    let mut moved_in: Vec<&str> = Vec::new();
    let result = (|| -> Result<()> {
        for f in &union.files {
            let t = target.join(f);
            if t.symlink_metadata().is_ok_and(|m| !m.is_dir()) {
                let b = backup.join(f);
                if let Some(p) = b.parent() {
                    std::fs::create_dir_all(p).map_err(|e| Error::io(&b, e))?;
                }
                std::fs::rename(&t, &b).map_err(|e| Error::io(&t, e))?;
                moved_out.push(f);
            }
        }
        for f in &new.files {
            let t = target.join(f);
            if let Some(p) = t.parent() {
                std::fs::create_dir_all(p).map_err(|e| Error::io(&t, e))?;
            }
            std::fs::rename(staging.join(f), &t).map_err(|e| Error::io(&t, e))?;
            moved_in.push(f);
        }
        Ok(())
    })();
    if let Err(e) = result {
        for f in moved_in {
            let _ = std::fs::remove_file(target.join(f));
        }
        for f in moved_out {
            let _ = std::fs::rename(backup.join(f), target.join(f));
        }
        let _ = write_manifest(target, old);
        let _ = std::fs::remove_dir_all(&backup);
        return Err(e);
    }
    write_manifest(target, new)?;
    // The new files are in place; the previous ones (in the backup) and the subfolders springfit
    // created that are now empty and no longer used can go.
    let _ = std::fs::remove_dir_all(&backup);
    let keep: BTreeSet<&str> = new.folders.iter().map(String::as_str).collect();
    for d in old.folders.iter().rev() {
        if !keep.contains(d.as_str()) {
            let _ = std::fs::remove_dir(target.join(d)); // fails, as wanted, unless empty
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
