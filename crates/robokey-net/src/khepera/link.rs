//! The byte stream to kh4server: a TCP connection or a serial device (a pseudo-terminal
//! pair made by `socat` on the robot, a Bluetooth `rfcomm` device, or the emulator's pty).
//!
//! Every read is bounded in length ([`MAX_REPLY_BYTES`]) and in time (the link's timeout
//! covers a whole reply, however slowly its bytes trickle in).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use serialport::SerialPort as _;

use crate::error::{NetError, is_wait_over};

/// Longest reply line accepted (bytes, line end included); kh4server's longest is ~60.
pub const MAX_REPLY_BYTES: usize = 128;

/// Requests of the startup synchronisation before it gives up.
const SYNC_ATTEMPTS: usize = 10;

/// A connected stream.
#[derive(Debug)]
enum Stream {
    Tcp(TcpStream),
    Serial(serialport::TTYPort),
}

impl Stream {
    fn set_timeout(&mut self, timeout: Duration) -> std::io::Result<()> {
        match self {
            Self::Tcp(stream) => stream.set_read_timeout(Some(timeout)),
            Self::Serial(port) => port.set_timeout(timeout).map_err(std::io::Error::from),
        }
    }

    fn as_io(&mut self) -> &mut dyn ReadWrite {
        match self {
            Self::Tcp(stream) => stream,
            Self::Serial(port) => port,
        }
    }
}

/// Read and write, as one trait object.
trait ReadWrite: Read + Write {}
impl<T: Read + Write> ReadWrite for T {}

/// A line-oriented connection to kh4server.
#[derive(Debug)]
pub struct Link {
    name: String,
    stream: Stream,
    timeout: Duration,
    /// Bytes received after the last line returned (at most [`MAX_REPLY_BYTES`]).
    pending: Vec<u8>,
}

impl Link {
    /// Opens `tcp:HOST:PORT` or a serial device path (a pty such as `/dev/pts/3`, or
    /// `/dev/rfcomm0`; set to 115200 baud, raw). A reply must arrive whole within `timeout`.
    ///
    /// # Errors
    /// The connection or device cannot be opened.
    pub fn open(spec: &str, timeout: Duration) -> Result<Self, NetError> {
        let stream = if let Some(address) = spec.strip_prefix("tcp:") {
            let stream = TcpStream::connect(address)
                .map_err(NetError::io(format!("connect to kh4server at {address}")))?;
            stream
                .set_nodelay(true)
                .map_err(NetError::io("set TCP_NODELAY"))?;
            Stream::Tcp(stream)
        } else {
            let port = serialport::new(spec, 115_200)
                .timeout(timeout)
                .open_native()
                .map_err(|e| NetError::io(format!("open kh4 device {spec}"))(e.into()))?;
            Stream::Serial(port)
        };
        Ok(Self::over(spec, stream, timeout))
    }

    fn over(name: &str, stream: Stream, timeout: Duration) -> Self {
        Self {
            name: name.to_owned(),
            stream,
            timeout,
            pending: Vec::with_capacity(MAX_REPLY_BYTES),
        }
    }

    /// Sends one request line and returns the reply line (without its line end). Bytes left
    /// from an earlier, failed exchange are discarded first.
    ///
    /// # Errors
    /// The link fails or closes; the reply is not text, longer than [`MAX_REPLY_BYTES`], or
    /// not complete within the timeout.
    pub fn request(&mut self, line: &str) -> Result<String, NetError> {
        self.pending.clear();
        self.send(line)?;
        self.read_line(Instant::now() + self.timeout)
            .map_err(|why| self.error(line, &why))
    }

    /// Synchronises with a kh4server that may have ignored the first line after connecting
    /// (its documented behaviour) or may hold half a line: sends an empty line, then `B`
    /// (firmware version) until a `b,…` reply comes. Returns that reply.
    ///
    /// # Errors
    /// No `b,` reply within `SYNC_ATTEMPTS` requests.
    pub fn synchronise(&mut self) -> Result<String, NetError> {
        self.send("\n")?;
        for _ in 0..SYNC_ATTEMPTS {
            self.send("B\n")?;
            let deadline = Instant::now() + self.timeout;
            // Replies to the blank line or to earlier requests come first: skip them.
            while let Ok(reply) = self.read_line(deadline) {
                if reply.starts_with("b,") {
                    return Ok(reply);
                }
            }
        }
        Err(self.error(
            "B",
            &format!("no `b,` reply to {SYNC_ATTEMPTS} version requests: is kh4server running?"),
        ))
    }

    fn error(&self, request: &str, why: &str) -> NetError {
        NetError::Kh4(format!(
            "{}: request {:?}: {why}",
            self.name,
            request.trim_end()
        ))
    }

    fn send(&mut self, line: &str) -> Result<(), NetError> {
        let io = self.stream.as_io();
        io.write_all(line.as_bytes())
            .and_then(|()| io.flush())
            .map_err(NetError::io(format!(
                "kh4 {}: send {:?}",
                self.name,
                line.trim_end()
            )))
    }

    /// Reads up to the next `\n`, before `deadline`.
    fn read_line(&mut self, deadline: Instant) -> Result<String, String> {
        let mut chunk = [0u8; 64];
        loop {
            if let Some(end) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=end).collect();
                let line = String::from_utf8(line)
                    .map_err(|_| "the reply is not text (invalid UTF-8)".to_owned())?;
                return Ok(line.trim_end_matches(['\r', '\n']).to_owned());
            }
            if self.pending.len() >= MAX_REPLY_BYTES {
                return Err(format!(
                    "the reply exceeds {MAX_REPLY_BYTES} bytes without a line end"
                ));
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(format!(
                    "no complete reply within {:.1} s",
                    self.timeout.as_secs_f64()
                ));
            }
            self.stream
                .set_timeout(left)
                .map_err(|e| format!("set the read timeout: {e}"))?;
            let room = (MAX_REPLY_BYTES - self.pending.len()).min(chunk.len());
            match self.stream.as_io().read(&mut chunk[..room]) {
                Ok(0) => return Err("the connection closed".to_owned()),
                Ok(n) => self.pending.extend_from_slice(&chunk[..n]),
                Err(e) if is_wait_over(&e) => {}
                Err(e) => return Err(format!("read failed: {e}")),
            }
        }
    }
}
