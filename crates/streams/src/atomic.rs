//! Atomic output: write next to the target under a temporary name, then rename.
//!
//! A crash never leaves half a file at the target path, and an existing file is only
//! replaced when the caller says so. The temporary files of a run that was killed are
//! removed by the next write of the same output; those of a run stopped by SIGINT/SIGTERM
//! by the binary's signal handler ([`remove_pending_temporaries`]).
use crate::StreamError;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// The longest file name the usual file systems (ext4, XFS, btrfs, tmpfs) take, in bytes.
const NAME_MAX: usize = 255;

/// Fails early (before any expensive work) when `path` cannot be written as asked.
///
/// Only regular files are written: an existing device, FIFO or socket is refused even with
/// `overwrite`, because writing means renaming a new file over it. An existing symbolic link
/// counts as an existing file; with `overwrite` the link itself is replaced, not its target.
pub fn check_writable(path: &Path, overwrite: bool) -> Result<(), StreamError> {
    if let Ok(target) = std::fs::metadata(path) {
        if target.is_dir() {
            return Err(StreamError::invalid(path, "is a directory, expected a file path"));
        }
        if !target.is_file() {
            return Err(StreamError::invalid(path, "is not a regular file (a device, FIFO or socket); cvtrace writes only regular files"));
        }
    }
    if path.symlink_metadata().is_ok() && !overwrite {
        return Err(StreamError::AlreadyExists { path: path.to_path_buf() });
    }
    let parent = parent_dir(path);
    if !parent.is_dir() {
        let why = if parent.exists() { "is a file, not a folder" } else { "does not exist" };
        return Err(StreamError::invalid(path, format!("output directory {} {why}", parent.display())));
    }
    if path.file_name().is_some_and(|n| n.len() > NAME_MAX) {
        return Err(StreamError::invalid(path, format!("the file name is longer than {NAME_MAX} bytes")));
    }
    // Whether the folder takes a new file is known only by making one: permission bits do not
    // say it for root, ACLs, read-only mounts or full quotas. The probe is the temporary name
    // the write will use, made and removed at once.
    let probe = temp_path_for(path);
    match PendingTemp::create(probe.clone()) {
        Ok((_pending, file)) => {
            drop(file);
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => Err(StreamError::invalid(path, format!("output directory {} is not writable: {e}", parent.display()))),
    }
}

/// Fails unless `path` ends in `.{ext}` (any case). The writers pick the format, not the name:
/// an OpenEXR file called `out.png` would mislead every viewer and tool that trusts the name.
pub fn check_extension(path: &Path, ext: &str) -> Result<(), StreamError> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)) {
        return Ok(());
    }
    let format = match ext {
        "exr" => "OpenEXR",
        "png" => "PNG",
        _ => ext,
    };
    Err(StreamError::invalid(path, format!("this output is written as {format}; give it a .{ext} file name")))
}

pub(crate) fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `(prefix, extension)` of the temporary siblings of `path`: `.{name}.tmp-{pid}{extension}`.
/// A name too long for that to fit in [`NAME_MAX`] bytes is shortened (at a character
/// boundary) and ends in a hash of the whole name, so two long names that share a beginning
/// still get different temporaries. The extension is kept for format libraries that look at
/// it, unless it is itself absurdly long.
pub(crate) fn temp_name_parts(path: &Path) -> (String, String) {
    let full = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    let ext = path.extension().map(|e| format!(".{}", e.to_string_lossy())).filter(|e| e.len() <= 16).unwrap_or_default();
    // "." + name + ".tmp-" + a pid of up to 10 digits + ext
    let room = NAME_MAX - (1 + 5 + 10 + ext.len());
    if full.len() <= room {
        return (format!(".{full}.tmp-"), ext);
    }
    // FNV-1a: stable across builds, so a later run recognises the temporaries of a killed one.
    let hash = full.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3));
    let mut name = full;
    while name.len() > room - 17 {
        name.pop();
    }
    (format!(".{name}~{hash:016x}.tmp-"), ext)
}

/// The temporary sibling used while `path` is being written. It keeps the extension so
/// that format libraries which look at it behave the same.
pub fn temp_path_for(path: &Path) -> PathBuf {
    let (prefix, ext) = temp_name_parts(path);
    parent_dir(path).join(format!("{prefix}{}{ext}", std::process::id()))
}

/// Removes temporary siblings of `path` left by runs that were killed. A temporary is stale
/// when no process holds its lock (a writer locks its temporary while it writes, see
/// [`create_temp`]; the lock goes when the process ends, however it ends) and, on Linux, when
/// no process here has the PID in its name either. The lock is what protects a live writer in
/// another PID namespace or on another machine sharing the folder.
fn remove_stale_temporaries(path: &Path) {
    let (prefix, ext) = temp_name_parts(path);
    let Ok(entries) = std::fs::read_dir(parent_dir(path)) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = name.strip_prefix(&prefix).and_then(|rest| rest.strip_suffix(&ext)) else { continue };
        let Ok(pid) = pid.parse::<u32>() else { continue };
        if pid == std::process::id() || !entry.file_type().is_ok_and(|t| t.is_file()) {
            continue;
        }
        let pid_gone = !cfg!(target_os = "linux") || !Path::new("/proc").join(pid.to_string()).exists();
        let unlocked = std::fs::File::open(entry.path()).is_ok_and(|f| f.try_lock().is_ok());
        if pid_gone && unlocked {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// What an interrupt must remove, for [`remove_pending_temporaries`]: the temporaries being
/// written, the lock files held, the folders being filled.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Registers a path to remove on interrupt (a temporary, a lock file, a folder being filled)
/// while it lives.
pub(crate) struct PendingTemp(pub(crate) PathBuf);

impl PendingTemp {
    pub(crate) fn new(path: PathBuf) -> PendingTemp {
        pending().push(path.clone());
        PendingTemp(path)
    }

    /// Creates the temporary file at `path` and registers it in one step under the list's
    /// lock: an interrupt either finds it registered (and removes it) or has locked the list
    /// for good (and this waits for the exit), never a file made after the clean-up.
    fn create(path: PathBuf) -> std::io::Result<(PendingTemp, std::fs::File)> {
        let mut list = pending();
        let file = create_temp(&path)?;
        list.push(path.clone());
        Ok((PendingTemp(path), file))
    }
}

impl Drop for PendingTemp {
    fn drop(&mut self) {
        // After `remove_pending_temporaries` the list stays locked for good: nothing to do.
        let mut list = match PENDING.try_lock() {
            Ok(list) => list,
            Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner(),
            Err(std::sync::TryLockError::WouldBlock) if INTERRUPTED.load(Ordering::SeqCst) => return,
            Err(std::sync::TryLockError::WouldBlock) => pending(),
        };
        if let Some(i) = list.iter().position(|p| *p == self.0) {
            list.swap_remove(i);
        }
    }
}

/// Set once [`remove_pending_temporaries`] has run: the process is about to end.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// True once [`remove_pending_temporaries`] has been called: work that fails afterwards
/// (its temporary file removed under it) should not report an error of its own.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Removes every temporary file that is being written, and the lock files of
/// [`crate::output_lock::OutputLock`]s: for a signal handler that is about to end the process, so that an
/// interrupted run leaves nothing behind. The list stays locked afterwards, so no new
/// temporary file can start (a writer that tries waits for the exit).
pub fn remove_pending_temporaries() {
    INTERRUPTED.store(true, Ordering::SeqCst);
    let mut list = pending();
    for p in list.drain(..) {
        // Folders are registered only by [`remove_folder_on_interrupt`], for folders this run made.
        if std::fs::symlink_metadata(&p).is_ok_and(|m| m.is_dir()) {
            // A writer that was past its registration may still move one finished file in
            // while the folder goes (then removing it fails, not empty); every later step of
            // it waits on the list, which stays locked: a few tries get the folder.
            for _ in 0..100 {
                if std::fs::remove_dir_all(&p).is_ok() || !p.exists() {
                    break;
                }
                std::thread::sleep(std::time::Duration::from_millis(2));
            }
        } else {
            let _ = std::fs::remove_file(p);
        }
    }
    std::mem::forget(list);
}

/// While the returned guard lives, an interrupt removes `folder` with everything in it. For a
/// folder the command has just made and fills in several steps (a report, the images of
/// `reconstruct --method all`), so that an interrupted run does not leave half of it behind;
/// drop the guard once the folder is complete. Never for a folder the user had.
pub struct FolderOnInterrupt {
    _registered: PendingTemp,
}

/// `std::fs::create_dir_all` that never runs after [`remove_pending_temporaries`]: it waits for
/// the process to end instead. Without it a command filling a folder on interrupt could make
/// the folder again, just after the handler removed it, and leave half of it behind.
pub fn create_dir_all(dir: &Path) -> Result<(), StreamError> {
    let _no_interrupt_meanwhile = pending();
    std::fs::create_dir_all(dir).map_err(|e| StreamError::Io { path: dir.to_path_buf(), error: e })
}

pub fn remove_folder_on_interrupt(folder: &Path) -> FolderOnInterrupt {
    FolderOnInterrupt { _registered: PendingTemp::new(folder.to_path_buf()) }
}

/// The outputs of one command that belong together (`compare --csv --json`, the images of
/// `reconstruct`): each is written atomically on its own, and the set is undone if the command
/// fails or is interrupted before [`OutputSet::keep`], so a failure half-way does not leave a
/// CSV without its JSON. Undoing removes only what the set created: a file that existed
/// before (replaced with `--force`) stays, since its old content is gone already.
#[derive(Default)]
pub struct OutputSet {
    created: Vec<PendingTemp>,
    folders: Vec<PendingTemp>,
}

impl OutputSet {
    pub fn new() -> OutputSet {
        OutputSet::default()
    }

    /// Runs `write`, which writes `path`; if `path` did not exist before and the write
    /// succeeds, the set will remove it again unless kept.
    pub fn write<T, E>(&mut self, path: &Path, write: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
        let existed = path.symlink_metadata().is_ok();
        let written = write()?;
        if !existed {
            self.created.push(PendingTemp::new(path.to_path_buf()));
        }
        Ok(written)
    }

    /// Creates the folder `dir` (and its parents) for the set's files; a folder the set made
    /// is removed with them, if nothing else was put into it meanwhile.
    pub fn create_dir_all(&mut self, dir: &Path) -> Result<(), StreamError> {
        let mut missing: Vec<PathBuf> =
            dir.ancestors().take_while(|d| !d.as_os_str().is_empty() && d.symlink_metadata().is_err()).map(Path::to_path_buf).collect();
        std::fs::create_dir_all(dir).map_err(|e| StreamError::Io { path: dir.to_path_buf(), error: e })?;
        // Outermost first, so that undoing (in reverse) removes the deepest first.
        missing.reverse();
        self.folders.extend(missing.into_iter().map(PendingTemp::new));
        Ok(())
    }

    /// The set is complete: nothing is removed any more.
    pub fn keep(mut self) {
        self.created.clear();
        self.folders.clear();
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for f in self.created.drain(..).rev() {
            let _ = std::fs::remove_file(&f.0);
        }
        for d in self.folders.drain(..).rev() {
            // Only if empty: the set never removes anything it did not write.
            let _ = std::fs::remove_dir(&d.0);
        }
    }
}

/// Moves the finished temporary file onto `path`. Without `overwrite` the move fails if `path`
/// exists by then, atomically (a hard link cannot replace a file), so two runs that finish
/// together cannot replace each other's output.
fn publish(tmp: &Path, path: &Path, overwrite: bool) -> Result<(), StreamError> {
    move_into_place(tmp, path, overwrite)?;
    // The move itself durable too (a directory entry is data of the directory).
    let _ = std::fs::File::open(parent_dir(path)).and_then(|d| d.sync_all());
    Ok(())
}

fn move_into_place(tmp: &Path, path: &Path, overwrite: bool) -> Result<(), StreamError> {
    if overwrite {
        // A replaced file keeps its permissions (a private output stays private).
        if let Ok(old) = std::fs::metadata(path) {
            let _ = std::fs::set_permissions(tmp, old.permissions());
        }
        return std::fs::rename(tmp, path).map_err(|e| StreamError::Io { path: path.to_path_buf(), error: e });
    }
    match std::fs::hard_link(tmp, path) {
        Ok(()) => {
            let _ = std::fs::remove_file(tmp);
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(StreamError::AlreadyExists { path: path.to_path_buf() }),
        // A file system without hard links: check, then rename (a small window remains).
        Err(_) => {
            if path.symlink_metadata().is_ok() {
                return Err(StreamError::AlreadyExists { path: path.to_path_buf() });
            }
            std::fs::rename(tmp, path).map_err(|e| StreamError::Io { path: path.to_path_buf(), error: e })
        }
    }
}

/// Creates `tmp` as a new, empty regular file and locks it for as long as the returned file is
/// open, which marks it as being written (see [`remove_stale_temporaries`]). Whatever was at
/// that name (a leftover of an earlier process with this PID, or a link planted to make us
/// write elsewhere) is removed first, never written through: `create_new` does not follow links.
fn create_temp(tmp: &Path) -> std::io::Result<std::fs::File> {
    let create = || std::fs::OpenOptions::new().write(true).create_new(true).open(tmp);
    let file = match create() {
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            std::fs::remove_file(tmp)?;
            create()
        }
        other => other,
    }?;
    // A file system without locks only loses the protection of live writers elsewhere.
    let _ = file.try_lock();
    Ok(file)
}

/// Removes a temporary whose write is unwinding: a panic, or a caller that stops the work by
/// unwinding out of it (the Python package on Ctrl-C), must not leave half a file behind. A
/// write that fails or finishes removes or publishes it itself.
struct RemoveOnUnwind<'a>(&'a Path);

impl Drop for RemoveOnUnwind<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            let _ = std::fs::remove_file(self.0);
        }
    }
}

/// Runs `write` on a temporary path, flushes it to disk and moves the result onto `path`.
/// On any error, or when the write unwinds, the temporary file is removed and `path` is untouched.
pub fn write_atomically<E>(path: &Path, overwrite: bool, write: impl FnOnce(&Path) -> Result<(), E>) -> Result<(), StreamError>
where
    E: std::fmt::Display,
{
    check_writable(path, overwrite)?;
    remove_stale_temporaries(path);
    let tmp = temp_path_for(path);
    let (_pending, _writing) =
        PendingTemp::create(tmp.clone()).map_err(|e| StreamError::invalid(path, format!("could not create {}: {e}", tmp.display())))?;
    let _unwinding = RemoveOnUnwind(&tmp);
    let written = write(&tmp).map_err(|e| e.to_string()).and_then(|()| {
        // Durable before it is visible: a crash after the rename must not leave an empty file.
        std::fs::File::open(&tmp).and_then(|f| f.sync_all()).map_err(|e| e.to_string())
    });
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(StreamError::invalid(path, format!("could not write: {e}")));
    }
    publish(&tmp, path, overwrite).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.exr");
        let r = write_atomically(&p, false, |tmp| {
            std::fs::write(tmp, b"half").unwrap();
            Err::<(), _>("boom")
        });
        assert!(r.is_err());
        assert!(!p.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn an_output_set_not_kept_takes_back_only_what_it_created() {
        let dir = tempfile::tempdir().unwrap();
        let old = dir.path().join("old.csv");
        std::fs::write(&old, b"the user's").unwrap();
        let folder = dir.path().join("a/b");
        let write = |p: &Path, text: &'static str| write_atomically(p, true, |tmp| std::fs::write(tmp, text));
        let mut set = OutputSet::new();
        set.create_dir_all(&folder).unwrap();
        set.write(&old, || write(&old, "replaced")).unwrap();
        set.write(&folder.join("x.json"), || write(&folder.join("x.json"), "new")).unwrap();
        // A failed write is not the set's to remove (there is nothing), and the error comes back.
        assert!(set.write(&dir.path().join("missing/y.json"), || write(&dir.path().join("missing/y.json"), "")).is_err());
        drop(set);
        assert!(!dir.path().join("a").exists(), "the folders and file the set made stay");
        assert_eq!(std::fs::read(&old).unwrap(), b"replaced", "a file that existed before is not removed");
        // A folder the set made that holds someone else's file stays, with that file.
        let mut set = OutputSet::new();
        set.create_dir_all(&folder).unwrap();
        set.write(&folder.join("x.json"), || write(&folder.join("x.json"), "new")).unwrap();
        std::fs::write(folder.join("other"), b"not the set's").unwrap();
        drop(set);
        assert!(!folder.join("x.json").exists() && folder.join("other").is_file());
        // Kept, everything stays.
        let mut set = OutputSet::new();
        let z = dir.path().join("z.csv");
        set.write(&z, || write(&z, "new")).unwrap();
        set.keep();
        assert!(z.is_file());
        assert!(!pending().iter().any(|p| p.starts_with(dir.path())), "a set leaves nothing registered for an interrupt");
    }

    #[test]
    fn refuses_to_overwrite_without_permission() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.txt");
        std::fs::write(&p, b"mine").unwrap();
        let r = write_atomically(&p, false, |tmp| std::fs::write(tmp, b"new").map_err(|e| e.to_string()));
        assert!(matches!(r, Err(StreamError::AlreadyExists { .. })));
        assert_eq!(std::fs::read(&p).unwrap(), b"mine");
        write_atomically(&p, true, |tmp| std::fs::write(tmp, b"new").map_err(|e| e.to_string())).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
    }

    #[test]
    fn extension_must_match_the_format() {
        assert!(check_extension(Path::new("out/a.exr"), "exr").is_ok());
        assert!(check_extension(Path::new("A.EXR"), "exr").is_ok());
        for bad in ["a.png", "a", "a.exr.tmp", "exr"] {
            let e = check_extension(Path::new(bad), "exr").unwrap_err().to_string();
            assert!(e.starts_with(bad) && e.contains("OpenEXR") && e.contains(".exr file name"), "{e}");
        }
        assert!(check_extension(Path::new("a.exr"), "png").unwrap_err().to_string().contains("PNG"));
    }

    #[test]
    fn special_files_and_directories_are_refused_even_with_overwrite() {
        let dir = tempfile::tempdir().unwrap();
        for overwrite in [false, true] {
            let e = check_writable(Path::new("/dev/null"), overwrite).unwrap_err().to_string();
            assert!(e.contains("/dev/null") && e.contains("not a regular file"), "{e}");
            let e = check_writable(dir.path(), overwrite).unwrap_err().to_string();
            assert!(e.contains("is a directory"), "{e}");
        }
        // A dangling link is an existing output too.
        let link = dir.path().join("l.exr");
        std::os::unix::fs::symlink(dir.path().join("nowhere"), &link).unwrap();
        assert!(matches!(check_writable(&link, false), Err(StreamError::AlreadyExists { .. })));
    }

    #[test]
    fn long_names_get_a_temporary_name_that_fits() {
        let dir = tempfile::tempdir().unwrap();
        let long = format!("{}é.exr", "a".repeat(246)); // 253 bytes
        let p = dir.path().join(&long);
        assert!(temp_path_for(&p).file_name().unwrap().len() <= NAME_MAX);
        write_atomically(&p, false, |tmp| std::fs::write(tmp, b"x")).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"x");
        let too_long = dir.path().join(format!("{}.exr", "a".repeat(252)));
        assert!(check_writable(&too_long, false).unwrap_err().to_string().contains("longer than 255 bytes"));
    }

    #[test]
    fn long_names_sharing_a_beginning_get_different_temporaries() {
        let (a, b) = (format!("{}.exr", "a".repeat(251)), format!("{}b.exr", "a".repeat(250)));
        let (ta, tb) = (temp_path_for(Path::new(&a)), temp_path_for(Path::new(&b)));
        assert_ne!(temp_name_parts(Path::new(&a)).0, temp_name_parts(Path::new(&b)).0);
        assert!(ta.file_name().unwrap().len() <= NAME_MAX && tb.file_name().unwrap().len() <= NAME_MAX);
        // An absurd extension is not kept.
        let long_ext = format!("s.{}", "c".repeat(250));
        assert!(temp_path_for(Path::new(&long_ext)).file_name().unwrap().len() <= NAME_MAX);
    }

    #[test]
    fn a_link_at_the_temporary_name_is_not_written_through() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim");
        std::fs::write(&victim, b"precious").unwrap();
        let p = dir.path().join("x.txt");
        std::os::unix::fs::symlink(&victim, temp_path_for(&p)).unwrap();
        write_atomically(&p, false, |tmp| std::fs::write(tmp, b"ours")).unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert!(std::fs::symlink_metadata(&p).unwrap().is_file(), "the output is a file, not the planted link");
        assert_eq!(std::fs::read(&p).unwrap(), b"ours");
    }

    #[test]
    fn a_replaced_file_keeps_its_permissions() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.txt");
        std::fs::write(&p, b"old").unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o600)).unwrap();
        write_atomically(&p, true, |tmp| std::fs::write(tmp, b"new")).unwrap();
        assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o600);
    }

    #[test]
    fn temporaries_of_dead_runs_are_removed_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.exr");
        let (prefix, ext) = temp_name_parts(&p);
        // PID 4194305 is above Linux's largest (2^22): never a live process.
        let dead = dir.path().join(format!("{prefix}4194305{ext}"));
        let alive = dir.path().join(format!("{prefix}1{ext}"));
        let other = dir.path().join(".y.exr.tmp-4194305.exr");
        // A writer whose PID means nothing here (another PID namespace, another machine)
        // but which holds its temporary's lock.
        let elsewhere = dir.path().join(format!("{prefix}4194306{ext}"));
        for f in [&dead, &alive, &other, &elsewhere] {
            std::fs::write(f, b"half").unwrap();
        }
        let held = std::fs::File::open(&elsewhere).unwrap();
        held.try_lock().unwrap();
        write_atomically(&p, false, |tmp| std::fs::write(tmp, b"x")).unwrap();
        assert!(!dead.exists());
        assert!(alive.exists() && other.exists(), "a live run's and another output's temporaries stay");
        assert!(elsewhere.exists(), "a locked temporary is being written");
    }

    #[test]
    fn without_overwrite_a_file_that_appears_meanwhile_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.txt");
        let r = write_atomically(&p, false, |tmp| {
            std::fs::write(&p, b"the other run's").unwrap();
            std::fs::write(tmp, b"ours")
        });
        assert!(matches!(r, Err(StreamError::AlreadyExists { .. })));
        assert_eq!(std::fs::read(&p).unwrap(), b"the other run's");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "the temporary file is gone");
    }

    #[test]
    fn temporaries_are_registered_while_they_are_written() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.txt");
        let mut seen = PathBuf::new();
        write_atomically(&p, false, |tmp| {
            assert!(pending().contains(&tmp.to_path_buf()));
            seen = tmp.to_path_buf();
            std::fs::write(tmp, b"x")
        })
        .unwrap();
        assert!(!pending().contains(&seen));
        // `remove_pending_temporaries` itself: tests/interrupted_write.rs (its own process).
    }

    #[test]
    fn missing_directory_is_reported() {
        let r = check_writable(Path::new("/nonexistent-dir-cvtrace/x.exr"), false);
        assert!(r.unwrap_err().to_string().contains("does not exist"));
        // A file where the folder should be is named as a file.
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("file.exr");
        std::fs::write(&file, b"x").unwrap();
        let e = check_writable(&file.join("sub.exr"), false).unwrap_err().to_string();
        assert!(e.contains("file.exr is a file, not a folder") && !e.contains("does not exist"), "{e}");
    }
}
