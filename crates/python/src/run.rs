//! Running cvtrace's work from Python: off the GIL, on a worker thread, with Ctrl-C answered.
//!
//! The calling thread releases the GIL and waits for the worker, taking the GIL back every
//! [`POLL`] to let Python run its signal handlers. On `KeyboardInterrupt` it raises the flag of
//! a [`Cancel`]; the work stops at its next cancellation point by unwinding with a
//! [`Cancelled`] payload (cvtrace's renders have no other way out mid-image: their progress
//! callback is the one place every render thread passes often). Unwinding drops every guard
//! on the way, so a stream file or reference being written loses its temporary file
//! (`cvtrace_streams::atomic`), an output claim its lock file, and nothing half-written is
//! left; finished files and a reference's checkpoint stay, as after Ctrl-C in the CLI. The
//! call then raises `KeyboardInterrupt`.
//!
//! Cancellation points: every tile of every render (through [`CancellingProgress`]) and every
//! call of an estimator written in Python. A reconstruction by a built-in estimator is not
//! interrupted half-way (it is pure computation and takes seconds): its result is dropped.
use pyo3::prelude::*;
use std::cell::RefCell;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

/// How often the waiting thread looks at Python's signals.
const POLL: Duration = Duration::from_millis(50);

/// The payload a cancelled work unwinds with.
pub struct Cancelled;

/// A request to stop, raised by the waiting thread on Ctrl-C.
#[derive(Default)]
pub struct Cancel(AtomicBool);

impl Cancel {
    pub fn is_set(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// Unwinds out of the work if it is cancelled: a cancellation point.
    pub fn check(&self) {
        if self.is_set() {
            std::panic::resume_unwind(Box::new(Cancelled));
        }
    }
}

thread_local! {
    /// The cancellation of the work running on this (worker) thread.
    static CURRENT: RefCell<Option<Arc<Cancel>>> = const { RefCell::new(None) };
    /// An exception a Python estimator raised on this thread, re-raised as itself by [`run`].
    static PYTHON_ERROR: RefCell<Option<PyErr>> = const { RefCell::new(None) };
}

/// The cancellation of the work on this thread, if it runs under [`run`].
pub fn current() -> Option<Arc<Cancel>> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Keeps the exception a Python estimator raised, so that the call raises it rather than
/// cvtrace's message about it.
pub fn keep_python_error(error: PyErr) {
    PYTHON_ERROR.with(|slot| *slot.borrow_mut() = Some(error));
}

/// A render progress that is a cancellation point.
pub struct CancellingProgress(pub Arc<Cancel>);

impl cvtrace_session::Progress for CancellingProgress {
    fn start(&self, _total: u64, _done: u64) {
        self.0.check();
    }

    fn advance(&self, _samples: u64) {
        self.0.check();
    }
}

/// Whether the worker has finished, for the waiting thread.
#[derive(Default)]
struct Done {
    finished: Mutex<bool>,
    signal: Condvar,
}

impl Done {
    fn set(&self) {
        *self.finished.lock().unwrap_or_else(|p| p.into_inner()) = true;
        self.signal.notify_all();
    }

    /// Waits up to `timeout`; whether the worker has finished.
    fn wait(&self, timeout: Duration) -> bool {
        let finished = self.finished.lock().unwrap_or_else(|p| p.into_inner());
        let (finished, _) = self.signal.wait_timeout_while(finished, timeout, |f| !*f).unwrap_or_else(|p| p.into_inner());
        *finished
    }
}

/// Sets [`Done`] when the worker ends, however it ends.
struct SetOnDrop<'a>(&'a Done);

impl Drop for SetOnDrop<'_> {
    fn drop(&mut self) {
        self.0.set();
    }
}

/// Runs `work` on a worker thread with the GIL released, on `threads` threads (`None`: all
/// cores), and turns its error into a Python exception: one a Python estimator raised as
/// itself, any other as `cvtrace.Error` with the CLI's message. Ctrl-C raises
/// `KeyboardInterrupt` (see the module doc).
pub fn run<T: Send>(py: Python<'_>, threads: Option<usize>, work: impl FnOnce(&Arc<Cancel>) -> anyhow::Result<T> + Send) -> PyResult<T> {
    let pool = match threads {
        None => None,
        Some(n) => Some(crate::errors::thread_pool(n)?),
    };
    let cancel = Arc::new(Cancel::default());
    let done = Done::default();
    let mut interrupted: Option<PyErr> = None;
    let outcome = std::thread::scope(|scope| {
        let worker = scope.spawn(|| {
            let _done = SetOnDrop(&done);
            // On the thread that runs `work` (a thread of `pool`, if there is one), where the
            // estimators are called.
            let body = || {
                CURRENT.with(|c| *c.borrow_mut() = Some(cancel.clone()));
                let result = std::panic::catch_unwind(AssertUnwindSafe(|| work(&cancel)));
                CURRENT.with(|c| *c.borrow_mut() = None);
                let python_error = PYTHON_ERROR.with(|slot| slot.borrow_mut().take());
                (result, python_error)
            };
            match &pool {
                Some(pool) => pool.install(body),
                None => body(),
            }
        });
        loop {
            if py.detach(|| done.wait(POLL)) {
                break;
            }
            if interrupted.is_none() {
                if let Err(e) = py.check_signals() {
                    cancel.0.store(true, Ordering::Relaxed);
                    interrupted = Some(e);
                }
            }
        }
        worker.join()
    });
    let (result, python_error) = match outcome {
        Ok(r) => r,
        Err(payload) => std::panic::resume_unwind(payload),
    };
    if let Some(e) = interrupted {
        return Err(e);
    }
    match result {
        Ok(Ok(value)) => Ok(value),
        Ok(Err(e)) => Err(python_error.unwrap_or_else(|| crate::errors::error(e))),
        Err(payload) if payload.is::<Cancelled>() => Err(pyo3::exceptions::PyKeyboardInterrupt::new_err("")),
        Err(payload) => match python_error {
            // A Python estimator's exception that unwound through a pure computation.
            Some(e) => Err(e),
            None => std::panic::resume_unwind(payload),
        },
    }
}
