//! Terminating signals (HUP, INT, TERM, QUIT, PIPE) as flags that the control loop and the
//! emulator poll, so that every way a run is told to end goes through its safe stop.
//!
//! The handlers, installed through `signal-hook`, only store into atomics (async-signal
//! safe). A closed terminal (HUP), Ctrl-C (INT), `kill` (TERM), Ctrl-\ (QUIT) and a closed
//! output pipe (PIPE) all end a run the same way: zero tension, torque off, the log
//! closed. SIGKILL cannot be caught; for it the servos' Bus Watchdog stops them. A
//! `softcbf verify` batch polls the same flag, and a second signal ends it at once
//! ([`exit_on_second_signal`]).

use std::sync::Arc;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// The flags set by the handlers.
struct Flags {
    stop: Arc<AtomicBool>,
    signal: Arc<AtomicUsize>,
}

static FLAGS: OnceLock<Flags> = OnceLock::new();

/// The signals that end a run through the safe stop.
#[cfg(unix)]
pub const TERMINATING: [i32; 5] = [
    signal_hook::consts::SIGHUP,
    signal_hook::consts::SIGINT,
    signal_hook::consts::SIGTERM,
    signal_hook::consts::SIGQUIT,
    signal_hook::consts::SIGPIPE,
];

fn flags() -> &'static Flags {
    FLAGS.get_or_init(|| {
        let flags = Flags {
            stop: Arc::new(AtomicBool::new(false)),
            signal: Arc::new(AtomicUsize::new(0)),
        };
        #[cfg(unix)]
        for signal in TERMINATING {
            // A signal that cannot be registered keeps its default action; the others
            // still work, so this is reported and not fatal.
            let registered =
                signal_hook::flag::register(signal, flags.stop.clone()).and_then(|_| {
                    signal_hook::flag::register_usize(signal, flags.signal.clone(), signal as usize)
                });
            if let Err(error) = registered {
                eprintln!("warning: cannot handle {}: {error}", name(signal as usize));
            }
        }
        flags
    })
}

/// Installs the handlers (idempotent) and returns the flag they set.
pub fn stop_flag() -> &'static AtomicBool {
    &flags().stop
}

/// After a first terminating signal, makes the second end the process at once with
/// `status`: for work that may stop anywhere (a `softcbf verify` batch, whose rows are
/// written whole as they finish), never for the hardware loop, which must stop safely.
/// Installs the handlers of [`stop_flag`] too; idempotent.
pub fn exit_on_second_signal(status: i32) {
    static ARMED: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    let _ = stop_flag();
    ARMED.get_or_init(|| {
        let armed = Arc::new(AtomicBool::new(false));
        #[cfg(unix)]
        for signal in TERMINATING {
            // The shutdown first: the first signal finds it disarmed, then arms it.
            let registered =
                signal_hook::flag::register_conditional_shutdown(signal, status, armed.clone())
                    .and_then(|_| signal_hook::flag::register(signal, armed.clone()));
            if let Err(error) = registered {
                eprintln!("warning: cannot handle {}: {error}", name(signal as usize));
            }
        }
        let _ = status;
        armed
    });
}

/// Whether a stop was requested.
pub fn stop_requested() -> bool {
    FLAGS.get().is_some_and(|f| f.stop.load(Ordering::SeqCst))
}

/// The last terminating signal received, if any (its number).
pub fn received() -> Option<usize> {
    FLAGS
        .get()
        .map(|f| f.signal.load(Ordering::SeqCst))
        .filter(|&s| s != 0)
}

/// The conventional name of signal `number`, with what usually sends it.
pub fn name(number: usize) -> &'static str {
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGPIPE, SIGQUIT, SIGTERM};
        let names = [
            (SIGHUP, "SIGHUP (terminal closed)"),
            (SIGINT, "SIGINT (Ctrl-C)"),
            (SIGQUIT, "SIGQUIT (Ctrl-\\)"),
            (SIGPIPE, "SIGPIPE (output closed)"),
            (SIGTERM, "SIGTERM"),
        ];
        if let Some((_, name)) = names.iter().find(|(s, _)| *s as usize == number) {
            return name;
        }
    }
    let _ = number;
    "a terminating signal"
}
