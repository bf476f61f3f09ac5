//! Whether batches may use rayon's global thread pool. A process forked after the pool has
//! started inherits the pool's bookkeeping but none of its threads: work sent there would
//! never run. A forked child therefore keeps every batch on its calling thread (the Python
//! bindings call `forked_child` from an at-fork hook); results are the same either way.

use std::sync::atomic::{AtomicBool, Ordering};

static POOL_STARTED: AtomicBool = AtomicBool::new(false);
static SERIAL_ONLY: AtomicBool = AtomicBool::new(false);

/// True when a batch may run on the thread pool (and records that the pool is in use).
pub fn pool_allowed() -> bool {
    if SERIAL_ONLY.load(Ordering::Relaxed) {
        return false;
    }
    POOL_STARTED.store(true, Ordering::Relaxed);
    true
}

/// To be called in a freshly forked child: if the parent had started the pool, stay serial.
pub fn forked_child() {
    if POOL_STARTED.load(Ordering::Relaxed) {
        SERIAL_ONLY.store(true, Ordering::Relaxed);
    }
}
