//! Ctrl-C during a long search. The core polls a stop request between batches of work, with
//! the GIL released; this one takes the GIL back briefly, at most every POLL_EVERY, to ask
//! Python whether a signal handler raised (KeyboardInterrupt), and keeps that error to raise.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use planarcal_core::HomographyError as CoreError;
use pyo3::prelude::*;

use crate::errors::to_py_in;

/// Often enough that Ctrl-C feels immediate, rarely enough to cost nothing measurable.
const POLL_EVERY: Duration = Duration::from_millis(50);

pub struct Signals {
    last_poll: Mutex<Instant>,
    raised: Mutex<Option<PyErr>>,
}

impl Signals {
    pub fn new() -> Self {
        Signals {
            last_poll: Mutex::new(Instant::now()),
            raised: Mutex::new(None),
        }
    }

    /// True when a signal handler raised: the search should stop.
    pub fn poll(&self) -> bool {
        {
            let mut last = self.last_poll.lock().unwrap_or_else(|p| p.into_inner());
            if last.elapsed() < POLL_EVERY {
                return false;
            }
            *last = Instant::now();
        }
        match Python::attach(|py| py.check_signals()) {
            Ok(()) => false,
            Err(e) => {
                *self.raised.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
                true
            }
        }
    }

    /// A core error as the exception to raise: the signal handler's own for an interruption.
    pub fn error(&self, e: CoreError, context: &str) -> PyErr {
        if matches!(e, CoreError::Interrupted { .. }) {
            if let Some(raised) = self.raised.lock().unwrap_or_else(|p| p.into_inner()).take() {
                return raised;
            }
        }
        to_py_in(e, context)
    }
}
