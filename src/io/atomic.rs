//! Output files and folders that never look complete before they are.
//!
//! Every unfinished output of the process (a `.partial` file, a staging
//! folder) is listed in one registry, so that a signal handler can remove
//! them all with [`remove_unfinished`] before the process exits: a run
//! stopped by Ctrl-C leaves nothing behind.

use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};

use crate::{Error, Result};

/// The unfinished outputs of this process: partial files and staging folders.
static UNFINISHED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn unfinished() -> MutexGuard<'static, Vec<PathBuf>> {
    UNFINISHED.lock().unwrap_or_else(PoisonError::into_inner)
}

fn unregister(list: &mut Vec<PathBuf>, path: &Path) {
    list.retain(|p| p != path);
}

/// Remove every partial file and staging folder this process has not
/// finished, and return their paths. For a signal handler that then exits:
/// the registry stays locked until the process ends, so no output can be
/// finished (renamed to its final name) after its partial file is gone.
/// Threads that go on writing write into removed files, which is harmless.
pub fn remove_unfinished() -> Vec<PathBuf> {
    let list = unfinished();
    for path in list.iter() {
        remove_path(path);
    }
    let removed = list.clone();
    // Hold the lock for the rest of the process's life.
    std::mem::forget(list);
    removed
}

/// Remove a file or a folder tree, retrying a few times for a folder that
/// another thread is still writing into.
fn remove_path(path: &Path) {
    const TRIES: usize = 10;
    if path.is_dir() {
        for _ in 0..TRIES {
            if fs::remove_dir_all(path).is_ok() || !path.exists() {
                return;
            }
        }
    } else {
        let _ = fs::remove_file(path);
    }
}

/// A file written under `<path>.partial-<pid>-<n>` (one per writer, so two
/// runs writing the same output do not write into one file) and renamed to
/// `path` by [`AtomicFile::finish`]: of two such runs the one that finishes
/// last wins, whole. Dropped without `finish` (an error, a panic that
/// unwinds), it deletes the partial file, so a half-written output never
/// sits under the final name. A process killed outright leaves at most a
/// partial file, removed by the next run that writes the same output. Note
/// that `std::process::exit` runs no destructors: drop or finish the file
/// before exiting.
///
/// Writes are buffered. Meant for regular files (`--out FILE.jsonl`,
/// overlay PNGs), not for devices or pipes.
pub struct AtomicFile {
    path: PathBuf,
    partial: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Create `<path>.partial-<pid>-<n>` for writing (`n` unique to this
    /// file, so runs whose process ids are the same, in containers, do not
    /// share it), locked while it is written; first remove the partial
    /// files of the same output that no run writes any more (unlocked and
    /// not modified for 5 s). A `path` that is an existing folder is an
    /// input error.
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        if path.is_dir() {
            return Err(Error::input(&path, "is a folder: the output must be a file name"));
        }
        let mut name = path.file_name().ok_or_else(|| Error::input(&path, "not a file name"))?.to_os_string();
        name.push(".partial-");
        remove_stale_partial_files(&parent_folder(&path), &name);
        name.push(format!("{}-{}", std::process::id(), unique_number()));
        let partial = path.with_file_name(name);
        let mut list = unfinished();
        let file = fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&partial)
            .map_err(|e| Error::input(&path, format!("cannot create: {e}")))?;
        // Where the file system has no locks, a stale partial file is left
        // for the user to remove instead.
        let _ = file.try_lock();
        list.push(partial.clone());
        Ok(Self { path, partial, writer: Some(BufWriter::new(file)) })
    }

    /// Write `bytes` to `path` atomically (through `<path>.partial-<pid>-<n>`).
    pub fn write_all_to(path: impl AsRef<Path>, bytes: &[u8]) -> Result<()> {
        let mut f = Self::create(path)?;
        f.write_all(bytes).map_err(|e| Error::io(&f.partial, e))?;
        f.finish()
    }

    /// The final path.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The path written until [`finish`](Self::finish).
    #[must_use]
    pub fn partial_path(&self) -> &Path {
        &self.partial
    }

    /// Flush, sync to disk, and rename the partial file to the final path.
    /// On failure the partial file is deleted. Errors name the final path.
    pub fn finish(mut self) -> Result<()> {
        let result = self.commit();
        if result.is_err() {
            let _ = fs::remove_file(&self.partial);
        }
        unregister(&mut unfinished(), &self.partial);
        result
    }

    fn commit(&mut self) -> Result<()> {
        let Some(writer) = self.writer.take() else {
            return Ok(());
        };
        let file = writer.into_inner().map_err(|e| Error::io(&self.path, e.into_error()))?;
        file.sync_all().map_err(|e| Error::io(&self.path, e))?;
        // Under the registry's lock: a signal handler either removes the
        // partial file before this or finds it finished. Renamed while still
        // open and locked, so no other run takes it for a stale one.
        let mut list = unfinished();
        fs::rename(&self.partial, &self.path).map_err(|e| Error::io(&self.path, e))?;
        unregister(&mut list, &self.partial);
        drop(file);
        Ok(())
    }

    fn writer(&mut self) -> io::Result<&mut BufWriter<File>> {
        self.writer.as_mut().ok_or_else(|| io::Error::other("AtomicFile already finished"))
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer()?.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer()?.flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(writer) = self.writer.take() {
            drop(writer);
            let _ = fs::remove_file(&self.partial);
            unregister(&mut unfinished(), &self.partial);
        }
    }
}

/// A file output named on the command line (`--out FILE`, `--plot FILE`):
/// an [`AtomicFile`] for a regular file or a name not yet taken, so that it
/// appears only when complete; an existing path that is neither a regular
/// file nor a folder (a device such as `/dev/null`, a named pipe) cannot be
/// replaced, and is written in place. Writes are buffered; errors name the
/// path.
pub enum OutputFile {
    /// Written under `<path>.partial-<pid>-<n>`, renamed by [`OutputFile::finish`].
    Atomic(AtomicFile),
    /// A device or a pipe, written directly.
    InPlace {
        /// The path given.
        path: PathBuf,
        /// The open device or pipe.
        writer: BufWriter<File>,
    },
}

impl OutputFile {
    /// Open `path` for writing: in place for an existing device or pipe
    /// (opening a named pipe waits for its reader), else as an
    /// [`AtomicFile`] (a folder is an input error).
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        match fs::metadata(path) {
            Ok(meta) if !meta.is_file() && !meta.is_dir() => {
                let file = fs::OpenOptions::new()
                    .write(true)
                    .open(path)
                    .map_err(|e| Error::input(path, format!("cannot open for writing: {e}")))?;
                Ok(Self::InPlace { path: path.to_path_buf(), writer: BufWriter::new(file) })
            }
            _ => AtomicFile::create(path).map(Self::Atomic),
        }
    }

    /// Write `bytes` to `path` ([`OutputFile::create`], then
    /// [`OutputFile::finish`]).
    pub fn write_all_to(path: impl AsRef<Path>, bytes: &[u8]) -> Result<()> {
        let path = path.as_ref();
        let mut file = Self::create(path)?;
        file.write_all(bytes).map_err(|e| Error::io(path, e))?;
        file.finish()
    }

    /// The path given.
    #[must_use]
    pub fn path(&self) -> &Path {
        match self {
            Self::Atomic(file) => file.path(),
            Self::InPlace { path, .. } => path,
        }
    }

    /// Flush what is written; an [`AtomicFile`] is then renamed to its
    /// final name ([`AtomicFile::finish`]). Errors name the path.
    pub fn finish(self) -> Result<()> {
        match self {
            Self::Atomic(file) => file.finish(),
            Self::InPlace { path, mut writer } => writer.flush().map_err(|e| Error::io(&path, e)),
        }
    }
}

impl Write for OutputFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Self::Atomic(file) => file.write(buf),
            Self::InPlace { writer, .. } => writer.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Self::Atomic(file) => file.flush(),
            Self::InPlace { writer, .. } => writer.flush(),
        }
    }
}

/// An output folder written in full or not at all: files go into a hidden
/// sibling staging folder `.<name>.partial-<pid>`, which
/// [`StagedDir::finish`] renames to the final name; dropped unfinished, the
/// staging folder is removed. The final folder must be absent or empty, so
/// sequences and overlays are never mixed. Staging folders for the same
/// folder left by processes that no longer run are removed on creation.
#[derive(Debug)]
pub struct StagedDir {
    dir: PathBuf,
    staging: PathBuf,
    finished: bool,
}

impl StagedDir {
    /// Check that `dir` is absent or an empty folder and create its staging folder.
    pub fn create(dir: &Path) -> Result<Self> {
        if dir.exists() {
            if !dir.is_dir() {
                return Err(Error::input(dir, "exists and is not a folder"));
            }
            if fs::read_dir(dir).map_err(|e| Error::io(dir, e))?.next().is_some() {
                return Err(Error::input(dir, "output folder exists and is not empty; remove it or pick another"));
            }
        }
        let name = dir.file_name().ok_or_else(|| Error::input(dir, "output folder has no name"))?.to_string_lossy();
        let parent = parent_folder(dir);
        fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        let prefix = format!(".{name}.partial-");
        remove_stale_staging(&parent, &prefix);
        let staging = parent.join(format!("{prefix}{}", std::process::id()));
        if staging.exists() {
            fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        let mut list = unfinished();
        fs::create_dir_all(&staging).map_err(|e| {
            Error::input(dir, format!("cannot create: {e} (it is written in {}, then renamed)", parent.display()))
        })?;
        list.push(staging.clone());
        Ok(Self { dir: dir.to_path_buf(), staging, finished: false })
    }

    /// The folder to write into until [`StagedDir::finish`].
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Move the staged folder to its final name.
    pub fn finish(mut self) -> Result<()> {
        if self.dir.exists() {
            // Empty (checked in `create`): replace it.
            fs::remove_dir(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        }
        let mut list = unfinished();
        fs::rename(&self.staging, &self.dir).map_err(|e| Error::io(&self.dir, e))?;
        unregister(&mut list, &self.staging);
        self.finished = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.finished {
            let _ = fs::remove_dir_all(&self.staging);
            unregister(&mut unfinished(), &self.staging);
        }
    }
}

/// The folder holding `path` (`.` for a bare name).
fn parent_folder(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A number no other [`AtomicFile`] of this process has, and unlikely in
/// another process of the same id (the clock's nanoseconds mixed in).
fn unique_number() -> u64 {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let count = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.subsec_nanos());
    (u64::from(nanos) << 20) ^ count
}

/// How old a partial file must be, unlocked, to be taken for stale: a new
/// one is created a moment before it is locked.
const STALE_AFTER: std::time::Duration = std::time::Duration::from_secs(5);

/// Remove the files in `parent` whose names start with `prefix` (an
/// output's `<name>.partial-`) that no run writes any more: not locked by
/// their writer (which holds the lock until the file is renamed) and not
/// modified for [`STALE_AFTER`]. Where the file system has no locks,
/// nothing is removed.
fn remove_stale_partial_files(parent: &Path, prefix: &std::ffi::OsStr) {
    let Ok(entries) = fs::read_dir(parent) else { return };
    for entry in entries.flatten() {
        if !entry.file_name().as_encoded_bytes().starts_with(prefix.as_encoded_bytes()) {
            continue;
        }
        let old = entry
            .metadata()
            .is_ok_and(|m| m.is_file() && m.modified().is_ok_and(|t| t.elapsed().is_ok_and(|age| age >= STALE_AFTER)));
        if !old {
            continue;
        }
        let path = entry.path();
        if fs::OpenOptions::new().write(true).open(&path).is_ok_and(|file| file.try_lock().is_ok()) {
            let _ = fs::remove_file(&path);
        }
    }
}

/// Remove the folders in `parent` named `<prefix><pid>` whose process no
/// longer runs. Whether a process runs is read from `/proc`; where there is
/// no `/proc`, nothing is removed.
fn remove_stale_staging(parent: &Path, prefix: &str) {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return;
    }
    let Ok(entries) = fs::read_dir(parent) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.strip_prefix(prefix)) else { continue };
        let alive =
            pid.parse::<u32>().map_or(true, |pid| pid == std::process::id() || proc.join(pid.to_string()).exists());
        if !alive && entry.path().is_dir() {
            let _ = fs::remove_dir_all(entry.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_path(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pipetrack-atomic-{}-{name}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        dir.join("out.jsonl")
    }

    #[test]
    fn atomic_file_appears_only_on_finish() {
        let path = temp_path("finish");
        let _ = fs::remove_file(&path);
        let mut f = AtomicFile::create(&path).unwrap();
        let partial = f.partial_path().to_path_buf();
        let name = partial.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with(&format!("out.jsonl.partial-{}-", std::process::id())), "{name}");
        assert_eq!(partial.parent(), path.parent());
        writeln!(f, "{{\"frame\":0}}").unwrap();
        f.flush().unwrap();
        assert!(!path.exists(), "nothing under the final name before finish");
        assert!(partial.exists());
        f.finish().unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "{\"frame\":0}\n");
        assert!(!partial.exists());
        fs::remove_dir_all(path.parent().unwrap()).unwrap();
    }

    /// A partial file of the same output that no run writes (unlocked, not
    /// modified for a while) is removed when the output is created again;
    /// one locked by its writer, or just made, is another run's and stays.
    #[test]
    fn stale_partial_files_are_removed_and_live_ones_kept() {
        let path = temp_path("stale");
        let partial = |n: &str| path.with_file_name(format!("out.jsonl.partial-{n}"));
        let (stale, locked, new) = (partial("7-1"), partial("7-2"), partial("7-3"));
        let long_ago = std::time::SystemTime::now() - 2 * STALE_AFTER;
        for p in [&stale, &locked, &new] {
            fs::write(p, "{\"frame\":0").unwrap();
        }
        for p in [&stale, &locked] {
            File::options().write(true).open(p).unwrap().set_modified(long_ago).unwrap();
        }
        let writer = File::options().write(true).open(&locked).unwrap();
        if writer.try_lock().is_err() {
            fs::remove_dir_all(path.parent().unwrap()).unwrap();
            return; // no file locks here: nothing is removed (documented)
        }
        AtomicFile::write_all_to(&path, b"new\n").unwrap();
        assert!(!stale.exists(), "the stale partial file is removed");
        assert!(locked.exists() && new.exists(), "a locked or new partial file stays");
        assert_eq!(fs::read_to_string(&path).unwrap(), "new\n");
        drop(writer);
        fs::remove_dir_all(path.parent().unwrap()).unwrap();
    }

    #[test]
    fn atomic_file_dropped_unfinished_leaves_nothing_and_keeps_old_output() {
        let path = temp_path("drop");
        fs::write(&path, "old complete output\n").unwrap();
        {
            let mut f = AtomicFile::create(&path).unwrap();
            f.write_all(b"half of a new").unwrap();
        }
        let left = fs::read_dir(path.parent().unwrap()).unwrap().flatten().filter(|e| e.file_name() != "out.jsonl");
        assert_eq!(left.count(), 0, "no partial file left");
        assert_eq!(fs::read_to_string(&path).unwrap(), "old complete output\n");
        AtomicFile::write_all_to(&path, b"new\n").unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "new\n");
        fs::remove_dir_all(path.parent().unwrap()).unwrap();
    }

    #[test]
    fn atomic_file_in_missing_folder_is_an_input_error() {
        let path = std::env::temp_dir().join("pipetrack-no-such-dir-xyz").join("out.jsonl");
        match AtomicFile::create(&path) {
            Err(Error::Input { path: p, message }) => {
                assert_eq!(p, path);
                assert!(message.starts_with("cannot create"), "{message}");
            }
            other => panic!("expected an input error, got {:?}", other.err()),
        }
    }
}
