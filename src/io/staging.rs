//! One output discipline for every command: each output is written under a temporary name unique
//! to the run, in the directory of its final name (`.NAME.RUNID.partial`, the same on every rank),
//! and all outputs of a command are renamed into place together at the end, only after every rank
//! has succeeded. A failing run therefore leaves the previous complete set untouched, and two runs
//! on one prefix never mix their files: the set of the last to finish replaces the other whole
//! (the renames of one set happen under an exclusive lock on each output directory). Before any
//! rename the set is checked: no two outputs may be one file, and no output may be a file the run
//! read ([`note_input`]), however the names are spelled; a refused set leaves every file as it was.
//!
//! The registry of pending temporaries is process-wide so that the signal handler of the binary can
//! remove them when the job is interrupted ([`discard_all`]), and its panic hook when a rank fails
//! inside ([`discard_after_panic`]). After the commit it tells the outputs an earlier run left
//! under a prefix from this run's ([`left_from_earlier`]). A target that exists and is not a
//! regular file (a symbolic link such as `/dev/stdout`, a pipe, a device node) is never renamed
//! over: it is written directly; a symbolic link to a regular file is followed, and its target is
//! replaced atomically like any other output ([`output_target`]).

use std::fs::File;
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::error::{Error, Result};

struct Registry {
    run_id: String,
    /// (final name, temporary name) of every output written so far and not yet committed.
    pending: Vec<(PathBuf, PathBuf)>,
    /// Outputs renamed into place by this run (a signal after the commit must not claim that
    /// nothing was replaced), by their final names.
    renamed: Vec<PathBuf>,
    /// The files this run has read, as named, which no output may replace.
    inputs: Vec<PathBuf>,
}

static REGISTRY: Mutex<Registry> = Mutex::new(Registry {
    run_id: String::new(),
    pending: Vec::new(),
    renamed: Vec::new(),
    inputs: Vec::new(),
});

fn registry() -> std::sync::MutexGuard<'static, Registry> {
    REGISTRY.lock().unwrap_or_else(|p| p.into_inner())
}

/// A run id for the temporary names: the batch job id where there is one, the process id, and
/// the clock, so that two runs on one prefix never share a temporary name. Chosen by one rank and
/// broadcast (see [`begin`]).
pub fn new_run_id() -> String {
    let job = ["SLURM_JOB_ID", "PBS_JOBID", "LSB_JOBID"]
        .iter()
        .find_map(|k| std::env::var(k).ok())
        .map(|j| j.chars().filter(char::is_ascii_alphanumeric).collect::<String>() + "-")
        .unwrap_or_default();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    format!("{job}{}-{nanos:09}", std::process::id())
}

/// Starts a run with the id `run_id` (the same on every rank); forgets any earlier pending outputs.
pub fn begin(run_id: &str) {
    let mut r = registry();
    r.run_id = run_id.to_string();
    r.pending.clear();
    r.renamed.clear();
    r.inputs.clear();
}

/// Records that this run reads the file `path` (called by the readers), so that the commit
/// refuses an output that would replace it.
pub fn note_input(path: &Path) {
    let mut r = registry();
    if !r.inputs.iter().any(|p| p == path) {
        r.inputs.push(path.to_path_buf());
    }
}

/// The temporary name of `path` in this run: `.NAME.RUNID.partial` beside it.
pub fn temp_path(path: &Path) -> PathBuf {
    let id = registry().run_id.clone();
    let id = if id.is_empty() { std::process::id().to_string() } else { id };
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.{id}.partial"))
}

/// Whether `path` exists and is not a regular file: a symbolic link (`/dev/stdout`, which leads to
/// a pipe or to a file opened by the shell), a pipe, a device node. Such a target is written
/// directly (through the link), never renamed over.
pub fn is_special(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| !m.is_file())
}

/// Where an output named `path` goes: a symbolic link to an existing regular file (neither under
/// `/dev` nor `/proc`) is followed, so that the new file replaces the link's target atomically, in
/// the target's directory, and the link stays a link; any other path is itself.
pub fn output_target(path: &Path) -> PathBuf {
    let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
    let system = |p: &Path| p.starts_with("/dev") || p.starts_with("/proc");
    if !is_link || system(path) {
        return path.to_path_buf();
    }
    match std::fs::canonicalize(path) {
        Ok(t) if !system(&t) && std::fs::metadata(&t).is_ok_and(|m| m.is_file()) => t,
        _ => path.to_path_buf(),
    }
}

/// Registers `path` (through [`output_target`]) as an output of this run and returns the temporary
/// name to write it under. Each output is registered once: [`commit_all`] refuses two outputs
/// that are one file.
pub fn register(path: &Path) -> PathBuf {
    let path = &output_target(path);
    let tmp = temp_path(path);
    // a name registered twice is kept twice: the commit refuses the set (one output replaced the
    // other under their one temporary name)
    registry().pending.push((path.to_path_buf(), tmp.clone()));
    tmp
}

/// Writes the output `path` of this run: `write` fills its temporary file, which waits for
/// [`commit_all`]; on failure it is removed at once. A special target is written directly.
pub fn stage(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    if is_special(&output_target(path)) {
        return write(path);
    }
    let tmp = register(path);
    write(&tmp).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        named_as_output(e, path, &tmp)
    })
}

/// An error about the temporary file `tmp` told as one about the output `path` the user named,
/// with the temporary name kept in the reason.
pub fn named_as_output(e: Error, path: &Path, tmp: &Path) -> Error {
    let reason = |r: String| format!("cannot be written (its temporary file {}: {r})", tmp.display());
    match e {
        Error::Io { path: p, reason: r } if p == tmp => Error::Io { path: path.into(), reason: reason(r) },
        Error::Hdf5 { path: p, reason: r } if p == tmp => {
            Error::Hdf5 { path: path.into(), reason: reason(r) }
        }
        e => e,
    }
}

/// Removes the temporary files of this run (errors ignored: a file may already be gone, removed
/// by another rank of the job that wrote it too) and forgets them. Returns the files this
/// process removed and how many outputs this run had already renamed into place. Waits for a
/// commit in progress ([`commit_all`] holds the registry throughout its renames), so the answer
/// describes a whole set: either no output was replaced, or all were.
pub fn discard_all() -> (Vec<PathBuf>, usize) {
    let mut r = registry();
    let removed =
        r.pending.iter().filter(|(_, t)| std::fs::remove_file(t).is_ok()).map(|(_, t)| t.clone()).collect();
    r.pending.clear();
    (removed, r.renamed.len())
}

/// [`discard_all`] for a panic hook: removes the temporary files of this run unless the registry
/// is held at the moment (by the panicking thread itself, in [`commit_all`], where waiting for it
/// would never end; or by another thread, which is discarding or committing the set already).
/// Returns how many were removed. A panic therefore leaves no `.NAME.RUNID.partial` file behind
/// but in that rare case.
pub fn discard_after_panic() -> usize {
    let mut r = match REGISTRY.try_lock() {
        Ok(r) => r,
        Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner(),
        Err(std::sync::TryLockError::WouldBlock) => return 0,
    };
    let removed = r.pending.iter().filter(|(_, t)| std::fs::remove_file(t).is_ok()).count();
    r.pending.clear();
    removed
}

/// Forgets the pending outputs without touching them (the ranks that do not rename).
pub fn forget_all() {
    registry().pending.clear();
}

/// Of the files `candidates` (the names a command may write under its prefix), those that exist
/// and were not renamed into place by this run: outputs of an earlier run under the same prefix
/// that this one did not write (`PREFIX.png` after a rerun with `--no-preview`, a
/// `PREFIX.trimmed.ply` after one without `--trim`). They are left alone; the caller names them.
/// Meaningful after [`commit_all`] on the rank that committed.
pub fn left_from_earlier(candidates: &[PathBuf]) -> Vec<PathBuf> {
    let r = registry();
    candidates
        .iter()
        // a special file is the user's own target, written directly by a run that names it
        .filter(|c| c.is_file() && !is_special(&output_target(c)))
        .filter(|c| !r.renamed.iter().any(|o| same_file(c, o)))
        .cloned()
        .collect()
}

/// Renames every pending output of this run into place, as a set: under an exclusive lock on each
/// output directory, so that two runs committing at once cannot interleave their renames. On a
/// failure the remaining temporaries are removed.
pub fn commit_all() -> Result<()> {
    // the registry stays locked until the last rename, so that a signal arriving meanwhile waits
    // for the set to be complete before it reports (see `discard_all`)
    let mut r = registry();
    let pending = std::mem::take(&mut r.pending);
    if let Err(e) = distinct_outputs(&pending, &r.inputs) {
        pending.iter().for_each(|(_, tmp)| drop(std::fs::remove_file(tmp)));
        return Err(e);
    }
    // the locks are released when the handles are dropped, after the last rename
    let _locks = lock_dirs(pending.iter().map(|(f, _)| parent_dir(f)));
    let mut result = Ok(());
    for (path, tmp) in &pending {
        if result.is_ok() {
            result = std::fs::rename(tmp, path).map_err(|e| Error::io(path, &e));
            if result.is_ok() {
                r.renamed.push(path.clone());
            }
        }
        if result.is_err() {
            let _ = std::fs::remove_file(tmp);
        }
    }
    result
}

/// Refuses a set of outputs in which two names are one file (`o.ply` and `./o.ply`, or a
/// `--timings` file named like a volume output: the later write replaced the earlier under their
/// one temporary name), or an output that is one of the run's inputs. Checked before anything is
/// renamed, so a refused set leaves every file as it was.
fn distinct_outputs(pending: &[(PathBuf, PathBuf)], inputs: &[PathBuf]) -> Result<()> {
    let refuse = |path: &Path, why: String| Err(Error::Usage(format!("{}: {why}", path.display())));
    for (at, (path, _)) in pending.iter().enumerate() {
        if let Some(input) = inputs.iter().find(|i| same_file(path, i)) {
            let why = format!(
                "this output would replace {}, an input of this run; choose another output name",
                input.display()
            );
            return refuse(path, why);
        }
        if let Some((other, _)) = pending[..at].iter().find(|(o, _)| same_file(path, o)) {
            let also =
                if other == path { String::new() } else { format!(" (also named {})", other.display()) };
            return refuse(
                path,
                format!("two outputs of this run are this one file{also}; give them different names"),
            );
        }
    }
    Ok(())
}

/// The device and inode of an existing file or directory (links followed).
fn file_id(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).map(|m| (m.dev(), m.ino())).ok()
}

/// Whether `a` and `b` name one file: the same existing file (device and inode, so also through
/// links), or, where one does not exist yet, the same name in the same directory however the
/// directory is spelled.
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (file_id(a), file_id(b)) {
        (Some(x), Some(y)) => x == y,
        _ => {
            a.file_name() == b.file_name()
                && file_id(&parent_dir(a)).is_some_and(|d| file_id(&parent_dir(b)) == Some(d))
        }
    }
}

/// The directory of `path`, `.` for a bare file name.
pub fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Exclusive advisory locks on the distinct directories among `dirs`, taken in the order of their
/// (device, inode), so that two runs locking overlapping sets cannot wait on each other. A
/// directory named twice in different spellings (`.` and its absolute path, `a/../b`, a link) is
/// locked once: a second `flock` of it on another descriptor would wait forever on this process's
/// own lock. A directory that cannot be opened or locked (a file system without locks) goes
/// unlocked: its renames go ahead all the same.
fn lock_dirs(dirs: impl Iterator<Item = PathBuf>) -> Vec<File> {
    use std::os::unix::fs::MetadataExt;
    let mut open: Vec<((u64, u64), File)> = dirs
        .filter_map(|d| File::open(d).ok())
        .filter_map(|f| f.metadata().ok().map(|m| ((m.dev(), m.ino()), f)))
        .collect();
    open.sort_by_key(|(id, _)| *id);
    open.dedup_by_key(|(id, _)| *id);
    open.into_iter()
        .map(|(_, f)| f)
        // SAFETY: flock on a descriptor owned by `f`, which outlives the call
        .filter(|f| unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX) } == 0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temp_name_is_hidden_beside_the_target_and_unique_to_the_run() {
        begin("r1");
        assert_eq!(temp_path(Path::new("out/a.ply")), PathBuf::from("out/.a.ply.r1.partial"));
        assert_ne!(new_run_id(), "");
        assert!(is_special(Path::new("/dev/null")));
        assert!(is_special(Path::new("/dev/stdout")));
        assert!(!is_special(Path::new("/nonexistent/x")));
        // in the same test: the registry is process-wide, and tests run side by side

        // a signal after the commit learns that the set was renamed
        let dir = std::env::temp_dir().join(format!("volspline-staging-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("a.txt");
        begin("r2");
        stage(&out, |tmp| std::fs::write(tmp, "new").map_err(|e| Error::io(tmp, &e))).unwrap();
        assert_eq!(discard_all(), (vec![temp_path(&out)], 0), "before the commit: removed, nothing replaced");
        assert!(!out.exists());
        stage(&out, |tmp| std::fs::write(tmp, "new").map_err(|e| Error::io(tmp, &e))).unwrap();
        commit_all().unwrap();
        assert_eq!(discard_all(), (vec![], 1), "after the commit: nothing to remove, one output replaced");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "new");

        // an output that is a link to a regular file: the target is replaced, the link stays
        let target = dir.join("t.txt");
        std::fs::write(&target, "old").unwrap();
        let link = dir.join("l.txt");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        stage(&link, |tmp| std::fs::write(tmp, "via link").map_err(|e| Error::io(tmp, &e))).unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "old", "nothing replaced before the commit");
        commit_all().unwrap();
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "via link");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_set_with_one_file_twice_or_an_input_is_refused() {
        let dir = std::env::temp_dir().join(format!("volspline-distinct-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let input = dir.join("points.xyz");
        std::fs::write(&input, "0 0 0\n").unwrap();
        let link = dir.join("link.xyz");
        std::os::unix::fs::symlink(&input, &link).unwrap();
        let inputs = [link.clone()];
        let set = |names: &[PathBuf]| names.iter().map(|p| (p.clone(), temp_path(p))).collect::<Vec<_>>();
        let (a, b) = (dir.join("o.ply"), dir.join("o.hdf"));
        assert!(distinct_outputs(&set(&[a.clone(), b.clone()]), &inputs).is_ok());
        for twice in [a.clone(), dir.join("sub/../o.ply"), dir.join("./sub/..//o.ply")] {
            let err = distinct_outputs(&set(&[a.clone(), b.clone(), twice.clone()]), &inputs).unwrap_err();
            assert!(
                err.to_string().contains("two outputs of this run are this one file"),
                "{twice:?}: {err}"
            );
            assert!(same_file(&a, &twice));
        }
        assert!(!same_file(&a, &b) && !same_file(&a, &dir.join("sub/o.ply")));
        // the input, named as it was read (a link) or as its target
        let err = distinct_outputs(&set(&[a.clone(), input.clone()]), &inputs).unwrap_err();
        assert!(err.to_string().contains("an input of this run"), "{err}");
        assert!(same_file(&link, &input) && same_file(&dir.join("sub/../link.xyz"), &input));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn one_directory_named_two_ways_is_locked_once() {
        let dir = std::env::temp_dir().join(format!("volspline-lock-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let spellings = [dir.clone(), dir.join("sub/.."), dir.join("sub").join("..")];
        // a second lock of the same directory would never return: wait for it on another thread
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || tx.send(lock_dirs(spellings.into_iter()).len()).unwrap());
        let held = rx.recv_timeout(std::time::Duration::from_secs(20));
        assert_eq!(held, Ok(1), "one lock for one directory, taken without waiting");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
