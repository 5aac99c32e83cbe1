//! The key server's listener: one thread per connection, at most [`MAX_CONNECTIONS`] at once
//! (more are closed at once), each connection one TLS handshake and one request within
//! [`CONNECTION_DEADLINE`] however slowly its bytes come, then `close_notify` and close. It
//! polls its stop request between connections and lets the open ones end before it returns.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use robokey::interrupt::Interrupt;
use rustls::ServerConnection;

use super::api::{KeyApi, error_response};
use super::http::{ReadError, read_request, write_response};
use super::tls::common_name;
use crate::error::NetError;

/// Most connections served at once.
pub const MAX_CONNECTIONS: usize = 16;
/// The longest a connection may take, handshake, request and response together.
pub const CONNECTION_DEADLINE: Duration = Duration::from_secs(10);
/// How often the listener looks at its stop request while no client connects.
const POLL: Duration = Duration::from_millis(50);
/// How long a refused request's remaining bytes are taken in before the connection closes.
const LINGER: Duration = Duration::from_secs(1);
/// How many of them at most.
const LINGER_BYTES: u64 = 1 << 20;
/// Longest request target a log line quotes (characters).
const LOGGED_TARGET: usize = 120;

/// A bound key server.
#[derive(Debug)]
pub struct KmeServer {
    listener: TcpListener,
    tls: Arc<rustls::ServerConfig>,
    api: Arc<KeyApi>,
}

impl KmeServer {
    /// Binds `address` (loopback unless told otherwise) for `api` under `tls`.
    ///
    /// # Errors
    /// The address cannot be bound.
    pub fn bind(
        address: SocketAddr,
        tls: Arc<rustls::ServerConfig>,
        api: KeyApi,
    ) -> Result<Self, NetError> {
        let listener = TcpListener::bind(address)
            .and_then(|listener| listener.set_nonblocking(true).map(|()| listener))
            .map_err(NetError::io(format!("listen on {address}")))?;
        Ok(Self {
            listener,
            tls,
            api: Arc::new(api),
        })
    }

    /// The address it listens on (the port the system chose for port 0).
    ///
    /// # Errors
    /// The socket cannot say.
    pub fn local_addr(&self) -> Result<SocketAddr, NetError> {
        self.listener
            .local_addr()
            .map_err(NetError::io("read the listening address"))
    }

    /// Serves until `interrupt` asks to stop, then waits for the open connections to end;
    /// `log` gets one line per connection (never a key's bits).
    ///
    /// # Errors
    /// Accepting fails for another reason than a client that went away or a lack of
    /// descriptors.
    pub fn serve(
        &self,
        interrupt: &Interrupt,
        log: &Arc<dyn Fn(&str) + Send + Sync>,
    ) -> Result<(), NetError> {
        let active = Arc::new(AtomicUsize::new(0));
        let mut threads: Vec<std::thread::JoinHandle<()>> = Vec::new();
        while !interrupt.is_requested() {
            let (stream, peer) = match self.listener.accept() {
                Ok(accepted) => accepted,
                Err(error) if error.kind() == std::io::ErrorKind::WouldBlock => {
                    std::thread::sleep(POLL);
                    continue;
                }
                Err(error) if transient(&error) => {
                    log(&format!("accept: {error}"));
                    std::thread::sleep(POLL);
                    continue;
                }
                Err(error) => return Err(NetError::io("accept a connection")(error)),
            };
            threads.retain(|thread| !thread.is_finished());
            if active.load(Ordering::SeqCst) >= MAX_CONNECTIONS {
                log(&format!(
                    "{peer}: closed at once, {MAX_CONNECTIONS} connections are open"
                ));
                continue;
            }
            let open = OpenConnection::count(&active);
            let (tls, api, log) = (
                Arc::clone(&self.tls),
                Arc::clone(&self.api),
                Arc::clone(log),
            );
            threads.push(std::thread::spawn(move || {
                let _open = open;
                log(&serve_connection(stream, peer, tls, &api));
            }));
        }
        for thread in threads {
            let _ = thread.join();
        }
        Ok(())
    }
}

/// One open connection in the count, until dropped (however its thread ends).
struct OpenConnection(Arc<AtomicUsize>);

impl OpenConnection {
    fn count(active: &Arc<AtomicUsize>) -> Self {
        active.fetch_add(1, Ordering::SeqCst);
        Self(Arc::clone(active))
    }
}

impl Drop for OpenConnection {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Whether an accept error concerns one client or a passing shortage, not the listener.
fn transient(error: &std::io::Error) -> bool {
    matches!(
        error.raw_os_error(),
        Some(
            nix::libc::ECONNABORTED
                | nix::libc::EMFILE
                | nix::libc::ENFILE
                | nix::libc::ENOBUFS
                | nix::libc::ENOMEM
                | nix::libc::EINTR
                | nix::libc::EPROTO
        )
    )
}

/// One connection: handshake, request, answer, close. Returns its log line.
fn serve_connection(
    stream: TcpStream,
    peer: SocketAddr,
    tls: Arc<rustls::ServerConfig>,
    api: &KeyApi,
) -> String {
    let mut socket = DeadlineStream {
        stream,
        deadline: Instant::now() + CONNECTION_DEADLINE,
    };
    let mut connection = match ServerConnection::new(tls) {
        Ok(connection) => connection,
        Err(error) => return format!("{peer}: TLS: {error}"),
    };
    if let Err(error) = socket.stream.set_nonblocking(false) {
        return format!("{peer}: {error}");
    }
    while connection.is_handshaking() {
        if let Err(error) = connection.complete_io(&mut socket) {
            return format!("{peer}: TLS handshake failed: {error}");
        }
    }
    let client = connection
        .peer_certificates()
        .and_then(|chain| chain.first())
        .and_then(|certificate| common_name(certificate));
    let who = format!(
        "{peer} SAE {}",
        client.as_deref().map_or_else(
            || "(no common name)".to_owned(),
            |c| c.escape_debug().to_string()
        )
    );
    let mut stream = rustls::Stream::new(&mut connection, &mut socket);
    let (response, line) = match read_request(&mut stream) {
        Ok(request) => {
            let answer = api.answer(&request, client.as_deref());
            let mut line = format!(
                "{who}: {} {} → {}",
                request.method,
                brief(&request.target),
                answer.response.status
            );
            if !answer.keys.is_empty() {
                let ids: Vec<String> = answer.keys.iter().map(ToString::to_string).collect();
                line += &format!(", keys {}", ids.join(" "));
            }
            if let Some(error) = &answer.error {
                line += &format!(": {error}");
            }
            (answer.response, line)
        }
        Err(ReadError::Refused(message)) => {
            let line = format!("{who}: → 400: {message}");
            (error_response(400, &message), line)
        }
        Err(ReadError::Io(error)) => return format!("{who}: no request: {error}"),
    };
    if let Err(error) = write_response(&mut stream, &response) {
        return format!("{line} (the response was not delivered: {error})");
    }
    connection.send_close_notify();
    let _ = connection.complete_io(&mut socket);
    if response.status == 400 {
        // A refused request may still be arriving (a body too long to read): take in what
        // comes for a moment, so that closing does not reset the connection before the
        // client has read the refusal.
        socket.deadline = socket.deadline.min(Instant::now() + LINGER);
        let mut stream = rustls::Stream::new(&mut connection, &mut socket);
        let _ = std::io::copy(&mut (&mut stream).take(LINGER_BYTES), &mut std::io::sink());
    }
    line
}

/// `target` as a log line quotes it.
fn brief(target: &str) -> String {
    if target.chars().count() <= LOGGED_TARGET {
        return target.to_owned();
    }
    let start: String = target.chars().take(LOGGED_TARGET).collect();
    format!("{start}… ({} characters)", target.chars().count())
}

/// A socket whose reads and writes all end by one deadline.
struct DeadlineStream {
    stream: TcpStream,
    deadline: Instant,
}

impl DeadlineStream {
    /// The time left, or a time-out error.
    fn left(&self) -> std::io::Result<Duration> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!(
                    "the connection took longer than {} s",
                    CONNECTION_DEADLINE.as_secs()
                ),
            ))
        } else {
            Ok(left)
        }
    }
}

impl Read for DeadlineStream {
    fn read(&mut self, buffer: &mut [u8]) -> std::io::Result<usize> {
        self.stream.set_read_timeout(Some(self.left()?))?;
        self.stream.read(buffer)
    }
}

impl Write for DeadlineStream {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.stream.set_write_timeout(Some(self.left()?))?;
        self.stream.write(bytes)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.stream.flush()
    }
}
