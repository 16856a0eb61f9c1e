//! What the binary's SIGINT/SIGTERM handler calls: every temporary file being written is
//! removed. A test binary of its own, since the call clears the whole process's list.
use cvtrace_streams::atomic::{remove_pending_temporaries, write_atomically};

#[test]
fn pending_temporaries_are_removed_and_the_output_is_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.exr");
    let r = write_atomically(&p, false, |tmp| {
        std::fs::write(tmp, b"half").unwrap();
        // The signal arrives mid-write.
        remove_pending_temporaries();
        assert!(!tmp.exists());
        Err::<(), _>("interrupted")
    });
    assert!(r.is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "nothing is left");
}
