//! What the binary's SIGINT/SIGTERM handler calls: every temporary file being written is
//! removed, and so is every folder a command made and has not finished filling. A test binary
//! of its own with one test, since the call clears (and then locks) the whole process's list.
use cvtrace_streams::atomic::{remove_folder_on_interrupt, remove_pending_temporaries, write_atomically};

#[test]
fn pending_temporaries_and_unfinished_folders_are_removed() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.exr");
    // A folder being filled (the images of a report, say) and one already finished.
    let (filling, done) = (dir.path().join("report"), dir.path().join("done"));
    for f in [&filling, &done] {
        std::fs::create_dir_all(f.join("images")).unwrap();
        std::fs::write(f.join("images/a.png"), b"png").unwrap();
    }
    let _filling = remove_folder_on_interrupt(&filling);
    drop(remove_folder_on_interrupt(&done));
    let r = write_atomically(&p, false, |tmp| {
        std::fs::write(tmp, b"half").unwrap();
        // The signal arrives mid-write.
        remove_pending_temporaries();
        assert!(!tmp.exists());
        Err::<(), _>("interrupted")
    });
    assert!(r.is_err());
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, ["done"], "only the finished folder is left");
}
