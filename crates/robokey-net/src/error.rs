//! Errors of the network shells.

/// What can go wrong in a network shell.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NetError {
    /// A socket, file or device operation failed.
    #[error("{context}: {error}")]
    Io {
        /// What was being done (names the address, file or device).
        context: String,
        /// The underlying error (part of the message, so not repeated as a source).
        error: std::io::Error,
    },
    /// The Khepera IV (or its emulator) answered something unexpected.
    #[error("kh4: {0}")]
    Kh4(String),
    /// The ROS 2 robot (or its emulator) is missing, silent, stale or sent something
    /// unusable.
    #[error("ros2: {0}")]
    Ros2(String),
    /// A capture file is malformed.
    #[error("{path}: {message}")]
    Capture {
        /// The capture file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// A store's journal or key file is malformed.
    #[error("{path}: {message}")]
    Store {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// A key is pending: the peer has not acknowledged it, so it is withheld.
    #[error("{0}")]
    Pending(String),
    /// No key of the length asked is available (yet): the store holds too few settled bits.
    #[error("{0}")]
    NoKey(String),
    /// Bad command-line or configuration input.
    #[error("{0}")]
    Usage(String),
    /// A stop was requested by signal n (SIGINT 2, SIGTERM 15).
    #[error("interrupted by {}", signal_name(*.0))]
    Interrupted(usize),
}

/// `SIGINT`, `SIGTERM`, or `signal N`.
#[must_use]
pub fn signal_name(signal: usize) -> String {
    match signal {
        2 => "SIGINT".to_owned(),
        15 => "SIGTERM".to_owned(),
        n => format!("signal {n}"),
    }
}

impl NetError {
    /// Whether the error is the user's input (exit 2): a flag, a file or a configuration that
    /// is refused, never a failure of the machine or the network (exit 1).
    #[must_use]
    pub fn is_usage(&self) -> bool {
        matches!(self, Self::Usage(_))
    }

    /// Wraps an I/O error with what was being done.
    pub fn io(context: impl Into<String>) -> impl FnOnce(std::io::Error) -> Self {
        let context = context.into();
        move |source| Self::Io {
            context,
            error: source,
        }
    }
}

/// Whether a read ended without data only because its wait did: a timeout, a non-blocking
/// socket with nothing to read, or a signal (EINTR). The caller looks at its deadline and its
/// stop request, then reads again.
#[must_use]
pub fn is_wait_over(error: &std::io::Error) -> bool {
    matches!(
        error.kind(),
        std::io::ErrorKind::WouldBlock
            | std::io::ErrorKind::TimedOut
            | std::io::ErrorKind::Interrupted
    )
}
