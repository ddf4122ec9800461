//! Ctrl-C (SIGINT) and SIGTERM as a flag that the control loop and the emulator poll, so
//! that both stop through their own safe paths instead of dying mid-packet.

use std::sync::atomic::{AtomicBool, Ordering};

static STOP: AtomicBool = AtomicBool::new(false);

#[cfg(unix)]
extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

/// Installs the handlers (idempotent) and returns the flag they set.
pub fn stop_flag() -> &'static AtomicBool {
    #[cfg(unix)]
    {
        static INSTALLED: std::sync::Once = std::sync::Once::new();
        INSTALLED.call_once(|| {
            for signal in [libc::SIGINT, libc::SIGTERM] {
                let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
                // SAFETY: `on_signal` has the `void (*)(int)` signature `signal` expects and
                // only performs an atomic store, which is async-signal-safe; it touches no
                // lock, allocation or I/O. Replacing the default handler of SIGINT/SIGTERM
                // affects no Rust invariant. The return value (the previous handler or
                // SIG_ERR) needs no action: on failure the default handler stays in place.
                unsafe {
                    libc::signal(signal, handler);
                }
            }
        });
    }
    &STOP
}

/// Whether a stop was requested.
pub fn stop_requested() -> bool {
    STOP.load(Ordering::SeqCst)
}
