//! Cancellation on SIGINT / SIGTERM.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use signal_hook::consts::{SIGINT, SIGTERM};

use super::BatchError;

/// Sets `cancel` on SIGINT or SIGTERM, so a running batch stops launching trials and writes
/// its reports; a second signal while `cancel` is already set ends the process at once
/// (exit status 128 + signal number).
pub fn cancel_on_signals(cancel: &Arc<AtomicBool>) -> Result<(), BatchError> {
    for signal in [SIGINT, SIGTERM] {
        // Registered first, so it sees the flag as it was before this signal set it.
        signal_hook::flag::register_conditional_shutdown(signal, 128 + signal, Arc::clone(cancel))
            .map_err(|source| BatchError::Signal { source })?;
        signal_hook::flag::register(signal, Arc::clone(cancel))
            .map_err(|source| BatchError::Signal { source })?;
    }
    Ok(())
}
