//! Exit codes, the same scheme for every command (README, "Exit codes"), and the signal
//! handlers that turn SIGINT and SIGTERM into a stop request.

use std::process::ExitCode;

use robokey::interrupt::Interrupt;

/// How a command that ran to its end ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Done; a session confirmed its key, or (private sensing) its kept doublets (exit 0).
    Success,
    /// A session ended without a key: aborted, or not confirmed by the peer (exit 3).
    NoKey,
    /// No peer proved it holds the pairing secret (exit 4).
    AuthenticationFailed,
    /// The session confirmed its key, but post-processing left a block or a final key in
    /// flight, pending until a later session settles it (exit 5).
    InFlight,
    /// Stopped by signal `n` after saving what it had (exit 128 + n: 130 for SIGINT, 143
    /// for SIGTERM).
    Interrupted(usize),
}

/// A problem with the command line or an input file: exit 2, as for clap's own errors.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Usage(pub String);

/// Returns early with a [`Usage`] error formatted like `format!`.
macro_rules! usage {
    ($($arg:tt)*) => {
        return Err(anyhow::Error::new($crate::exit::Usage(format!($($arg)*))))
    };
}
pub(crate) use usage;

/// Exit code of a failure: 5 for a pending key (`keys take`, `keys get`, `keys delete`), 3
/// when no key is available yet (`keys take`), 2 when the input was wrong, 1 otherwise (I/O, a
/// runtime error, a store file that does not verify).
fn failure_code(error: &anyhow::Error) -> u8 {
    use robokey_net::NetError;
    let net = error
        .chain()
        .filter_map(|cause| cause.downcast_ref::<NetError>());
    if net.clone().any(|e| matches!(e, NetError::Pending(_))) {
        5
    } else if net.clone().any(|e| matches!(e, NetError::NoKey(_))) {
        3
    } else if error.chain().any(is_usage) {
        2
    } else {
        1
    }
}

/// Whether one cause of a failure is the user's input: each error type of the crates the
/// commands call answers for itself.
fn is_usage(cause: &(dyn std::error::Error + 'static)) -> bool {
    use robokey_lab::LabError;
    use robokey_net::NetError;
    if let Some(e) = cause.downcast_ref::<LabError>() {
        e.is_usage()
    } else if let Some(e) = cause.downcast_ref::<robokey::config::ConfigError>() {
        e.is_usage()
    } else if let Some(e) = cause.downcast_ref::<NetError>() {
        e.is_usage()
    } else {
        cause.is::<Usage>()
    }
}

/// The process's exit code for a command's result; prints the error.
pub fn code(result: anyhow::Result<Status>) -> ExitCode {
    match result {
        Ok(Status::Success) => ExitCode::SUCCESS,
        Ok(Status::NoKey) => ExitCode::from(3),
        Ok(Status::AuthenticationFailed) => ExitCode::from(4),
        Ok(Status::InFlight) => ExitCode::from(5),
        Ok(Status::Interrupted(signal)) => ExitCode::from(128 + (signal as u8 & 0x7f)),
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::from(failure_code(&error))
        }
    }
}

/// Turns SIGINT and SIGTERM into a stop request that the command polls; a second signal
/// while the first is being handled ends the process at once (exit 1).
///
/// # Errors
/// The handlers cannot be registered.
pub fn on_signals() -> anyhow::Result<Interrupt> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    use signal_hook::flag;
    let interrupt = Interrupt::new();
    let requested = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [SIGINT, SIGTERM] {
        // Registered first, so it sees the flag as the previous signal left it.
        flag::register_conditional_shutdown(signal, 1, std::sync::Arc::clone(&requested))?;
        flag::register(signal, std::sync::Arc::clone(&requested))?;
        flag::register_usize(signal, interrupt.flag(), signal as usize)?;
    }
    Ok(interrupt)
}

/// Ends the process as the default action of SIGPIPE would once stdout's reader is gone
/// (`robokey secrecy DIR | head`), instead of panicking in `println!` (Rust ignores SIGPIPE).
/// Only for commands that write files and the terminal: the network agents keep SIGPIPE
/// ignored, so a closed socket is an error they handle.
pub fn end_on_broken_pipe() {
    use signal_hook::consts::SIGPIPE;
    let always = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    // Registration fails only for forbidden signals, and SIGPIPE is not one: if it ever did,
    // a broken pipe would panic as before.
    let _ = signal_hook::flag::register_conditional_default(SIGPIPE, always);
}
