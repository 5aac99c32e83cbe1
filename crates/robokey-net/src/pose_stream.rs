//! Pose streams (docs/sensors.md): what the world's sensors serve over TCP and what a
//! recorder writes to a file, in one format: a header line `step,x,y,theta`, then one line
//! `k,x,y,θ` per sample instant `t_k` (m, m, rad), numbers in the shortest decimal form that
//! parses back to the same `f64`, so a reader sees exactly the sampled values.

use std::io::{BufRead, BufReader, BufWriter, ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use robokey::model::Pose;

use crate::error::NetError;

/// The header line of every pose stream and log.
pub const HEADER: &str = "step,x,y,theta";

/// Longest line a reader accepts (bytes, newline excluded); longer ones are skipped.
pub const MAX_LINE_BYTES: usize = 256;

/// Most samples a server keeps for clients that connect late (≈ 60 MB of lines); later
/// samples reach only the clients connected by then.
pub const MAX_BACKLOG_SAMPLES: usize = 1 << 20;

/// Most samples a log file may hold: a session is at most 10⁷ steps.
pub const MAX_LOG_SAMPLES: usize = 10_000_001;

/// How long a server waits for a slow client to take a line before dropping it.
const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// One sample of a pose stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSample {
    /// Step k: the sample instant `t_k = k·T`.
    pub step: u32,
    /// The measured pose (m, m, rad).
    pub pose: Pose,
}

impl PoseSample {
    /// Its line, newline included.
    #[must_use]
    pub fn line(&self) -> String {
        let p = &self.pose;
        format!("{},{:?},{:?},{:?}\n", self.step, p.x, p.y, p.z)
    }

    /// Parses a line (without its newline).
    ///
    /// # Errors
    /// What is wrong with it; never panics.
    pub fn parse(line: &str) -> Result<Self, &'static str> {
        let mut fields = line.trim_end_matches('\r').split(',');
        let step = fields
            .next()
            .and_then(|s| s.parse::<u32>().ok())
            .ok_or("the step is not a whole number")?;
        let mut pose = [0.0; 3];
        for value in &mut pose {
            *value = fields
                .next()
                .and_then(|s| s.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or("a coordinate is not a finite number")?;
        }
        if fields.next().is_some() {
            return Err("more than four fields");
        }
        Ok(Self {
            step,
            pose: pose.into(),
        })
    }
}

/// What the server threads share.
#[derive(Debug, Default)]
struct Shared {
    clients: Vec<TcpStream>,
    /// The lines of the current session, for clients that connect late.
    backlog: String,
    samples: usize,
}

impl Shared {
    /// Sends `text` to every client, dropping those that fail or stall.
    fn send(&mut self, text: &str) {
        self.clients
            .retain_mut(|client| client.write_all(text.as_bytes()).is_ok());
    }

    /// Ends the stream for every client (they read end of file).
    fn close_clients(&mut self) {
        for client in self.clients.drain(..) {
            let _ = client.shutdown(Shutdown::Both);
        }
    }
}

/// Serves one pose stream on TCP to any number of clients: each gets the header, the
/// session's samples so far, then every new one.
#[derive(Debug)]
pub struct PoseServer {
    address: SocketAddr,
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    acceptor: Option<JoinHandle<()>>,
}

impl PoseServer {
    /// Listens on `address` (port 0: any).
    ///
    /// # Errors
    /// The address cannot be bound.
    pub fn bind(address: SocketAddr) -> Result<Self, NetError> {
        let listener =
            TcpListener::bind(address).map_err(NetError::io(format!("bind TCP {address}")))?;
        let address = listener
            .local_addr()
            .map_err(NetError::io("local address"))?;
        listener
            .set_nonblocking(true)
            .map_err(NetError::io("set the listener non-blocking"))?;
        let shared = Arc::new(Mutex::new(Shared::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let acceptor = {
            let (shared, stop) = (Arc::clone(&shared), Arc::clone(&stop));
            std::thread::spawn(move || accept(&listener, &shared, &stop))
        };
        Ok(Self {
            address,
            shared,
            stop,
            acceptor: Some(acceptor),
        })
    }

    /// The bound address.
    #[must_use]
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// Sends a sample to every client.
    pub fn publish(&self, sample: &PoseSample) {
        let line = sample.line();
        let mut shared = self.shared.lock().unwrap_or_else(PoisonError::into_inner);
        if shared.samples < MAX_BACKLOG_SAMPLES {
            shared.backlog.push_str(&line);
            shared.samples += 1;
        }
        shared.send(&line);
    }

    /// Ends the session's stream: its clients read end of file, and later clients get only
    /// the next session's samples.
    pub fn end_session(&self) {
        let mut shared = self.shared.lock().unwrap_or_else(PoisonError::into_inner);
        shared.close_clients();
        shared.backlog.clear();
        shared.samples = 0;
    }
}

impl Drop for PoseServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(acceptor) = self.acceptor.take() {
            let _ = acceptor.join();
        }
        self.end_session();
    }
}

/// Accepts clients until `stop`, polling every 10 ms.
fn accept(listener: &TcpListener, shared: &Mutex<Shared>, stop: &AtomicBool) {
    while !stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((mut client, _)) => {
                let ready = client.set_nonblocking(false).is_ok()
                    && client.set_write_timeout(Some(WRITE_TIMEOUT)).is_ok()
                    && client.set_nodelay(true).is_ok();
                let mut shared = shared.lock().unwrap_or_else(PoisonError::into_inner);
                let welcome = format!("{HEADER}\n{}", shared.backlog);
                if ready && client.write_all(welcome.as_bytes()).is_ok() {
                    shared.clients.push(client);
                }
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(10));
            }
            Err(_) => std::thread::sleep(Duration::from_millis(10)),
        }
    }
}

/// What a client read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reading {
    /// A sample.
    Sample(PoseSample),
    /// Nothing before the deadline.
    Nothing,
    /// The stream ended.
    Ended,
}

/// A client of a [`PoseServer`]: reads its samples, skipping the header and malformed or
/// overlong lines (counted).
#[derive(Debug)]
pub struct PoseStreamClient {
    stream: TcpStream,
    address: SocketAddr,
    /// Bytes of the line being read.
    pending: Vec<u8>,
    /// Inside an overlong line: drop bytes up to its newline.
    skipping: bool,
    malformed: u64,
}

impl PoseStreamClient {
    /// Connects to the stream at `address`, trying for up to `timeout`.
    ///
    /// # Errors
    /// Nothing accepts the connection in time.
    pub fn connect(address: SocketAddr, timeout: Duration) -> Result<Self, NetError> {
        let stream = TcpStream::connect_timeout(&address, timeout).map_err(NetError::io(
            format!("connect to the pose stream at {address}"),
        ))?;
        stream
            .set_nodelay(true)
            .map_err(NetError::io("set TCP_NODELAY"))?;
        Ok(Self {
            stream,
            address,
            pending: Vec::new(),
            skipping: false,
            malformed: 0,
        })
    }

    /// The stream's address.
    #[must_use]
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// Lines skipped because they were malformed or longer than [`MAX_LINE_BYTES`].
    #[must_use]
    pub fn malformed(&self) -> u64 {
        self.malformed
    }

    /// The next sample, waiting until `deadline`.
    ///
    /// # Errors
    /// The socket fails.
    pub fn next_until(&mut self, deadline: Instant) -> Result<Reading, NetError> {
        let mut chunk = [0u8; 4096];
        loop {
            if let Some(end) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=end).collect();
                let text = std::str::from_utf8(&line[..end]).unwrap_or("");
                if text.trim_end_matches('\r') == HEADER {
                    continue;
                }
                match PoseSample::parse(text) {
                    Ok(sample) => return Ok(Reading::Sample(sample)),
                    Err(_) => self.malformed += 1,
                }
                continue;
            }
            if self.pending.len() > MAX_LINE_BYTES {
                self.pending.clear();
                self.skipping = true;
                self.malformed += 1;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(Reading::Nothing);
            }
            self.stream
                .set_read_timeout(Some(left.max(Duration::from_micros(100))))
                .map_err(NetError::io("set the pose stream's timeout"))?;
            let n = match self.stream.read(&mut chunk) {
                Ok(0) => return Ok(Reading::Ended),
                Ok(n) => n,
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    continue;
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => {
                    return Err(NetError::io(format!(
                        "read the pose stream at {}",
                        self.address
                    ))(e));
                }
            };
            let mut bytes = &chunk[..n];
            if self.skipping {
                match bytes.iter().position(|&b| b == b'\n') {
                    Some(end) => {
                        self.skipping = false;
                        bytes = &bytes[end + 1..];
                    }
                    None => continue,
                }
            }
            self.pending.extend_from_slice(bytes);
        }
    }
}

/// Records the stream at `address` to a log file at `path` until the stream ends or
/// `stop()` says so (polled every 50 ms); returns the samples written. The file is created
/// new (an existing one is refused) and flushed as it grows.
///
/// # Errors
/// The stream cannot be reached, or the file cannot be written.
pub fn record(address: SocketAddr, path: &Path, stop: impl Fn() -> bool) -> Result<u64, NetError> {
    let mut client = PoseStreamClient::connect(address, Duration::from_secs(5))?;
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(NetError::io(format!("create {}", path.display())))?;
    let write_error = || NetError::io(format!("write {}", path.display()));
    let mut out = BufWriter::new(file);
    writeln!(out, "{HEADER}").map_err(write_error())?;
    let mut written = 0;
    while !stop() {
        match client.next_until(Instant::now() + Duration::from_millis(50))? {
            Reading::Sample(sample) => {
                out.write_all(sample.line().as_bytes())
                    .map_err(write_error())?;
                written += 1;
            }
            Reading::Nothing => out.flush().map_err(write_error())?,
            Reading::Ended => break,
        }
    }
    out.flush().map_err(write_error())?;
    Ok(written)
}

/// Reads a pose log (e.g. Eve's camera, recorded by [`record`]): its samples in file order.
///
/// # Errors
/// The file cannot be read, lacks the header, holds a malformed line (named by its
/// number), or more than [`MAX_LOG_SAMPLES`] samples.
pub fn read_log(path: &Path) -> Result<Vec<PoseSample>, NetError> {
    let bad = |message: String| NetError::Capture {
        path: path.display().to_string(),
        message,
    };
    let file =
        std::fs::File::open(path).map_err(NetError::io(format!("open {}", path.display())))?;
    let mut lines =
        BufReader::new(file.take((MAX_LOG_SAMPLES as u64 + 1) * (MAX_LINE_BYTES as u64 + 1)))
            .lines();
    match lines.next() {
        Some(Ok(header)) if header.trim_end_matches('\r') == HEADER => {}
        _ => {
            return Err(bad(format!(
                "not a pose log: the first line is not `{HEADER}`"
            )));
        }
    }
    let mut samples = Vec::new();
    for (number, line) in lines.enumerate() {
        let line = line.map_err(NetError::io(format!("read {}", path.display())))?;
        if line.len() > MAX_LINE_BYTES {
            return Err(bad(format!("line {} is too long", number + 2)));
        }
        if samples.len() >= MAX_LOG_SAMPLES {
            return Err(bad(format!("more than {MAX_LOG_SAMPLES} samples")));
        }
        let sample =
            PoseSample::parse(&line).map_err(|why| bad(format!("line {}: {why}", number + 2)))?;
        samples.push(sample);
    }
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sample(step: u32, x: f64) -> PoseSample {
        PoseSample {
            step,
            pose: Pose::new(x, -x / 3.0, 1e-300 * x),
        }
    }

    #[test]
    fn a_server_streams_the_backlog_and_new_samples_then_ends() {
        let server = PoseServer::bind("127.0.0.1:0".parse().unwrap()).unwrap();
        server.publish(&sample(0, 0.1));
        let mut client =
            PoseStreamClient::connect(server.address(), Duration::from_secs(1)).unwrap();
        let deadline = || Instant::now() + Duration::from_secs(2);
        assert_eq!(
            client.next_until(deadline()).unwrap(),
            Reading::Sample(sample(0, 0.1))
        );
        server.publish(&sample(1, 0.2));
        assert_eq!(
            client.next_until(deadline()).unwrap(),
            Reading::Sample(sample(1, 0.2))
        );
        assert_eq!(
            client
                .next_until(Instant::now() + Duration::from_millis(20))
                .unwrap(),
            Reading::Nothing
        );
        server.end_session();
        assert_eq!(client.next_until(deadline()).unwrap(), Reading::Ended);
    }

    #[test]
    fn a_client_skips_malformed_and_overlong_lines() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let address = listener.local_addr().unwrap();
        let writer = std::thread::spawn(move || {
            let (mut peer, _) = listener.accept().unwrap();
            let long = "9".repeat(5000);
            let text = format!(
                "{HEADER}\n1,2\n{long}\nx,1,2,3\n2,NaN,0,0\n{}",
                sample(3, 0.5).line()
            );
            peer.write_all(text.as_bytes()).unwrap();
        });
        let mut client = PoseStreamClient::connect(address, Duration::from_secs(1)).unwrap();
        let got = client
            .next_until(Instant::now() + Duration::from_secs(2))
            .unwrap();
        assert_eq!(got, Reading::Sample(sample(3, 0.5)));
        assert_eq!(client.malformed(), 4);
        writer.join().unwrap();
        assert_eq!(
            client
                .next_until(Instant::now() + Duration::from_secs(2))
                .unwrap(),
            Reading::Ended
        );
    }

    proptest! {
        #[test]
        fn lines_round_trip_exactly(step in any::<u32>(), x in proptest::num::f64::NORMAL | proptest::num::f64::SUBNORMAL | proptest::num::f64::ZERO, y in -1e3..1e3f64, z in -1e3..1e3f64) {
            let s = PoseSample { step, pose: Pose::new(x, y, z) };
            let line = s.line();
            prop_assert!(line.len() <= MAX_LINE_BYTES);
            let back = PoseSample::parse(line.trim_end()).unwrap();
            prop_assert_eq!(back.step, s.step);
            for i in 0..3 {
                prop_assert_eq!(back.pose[i].to_bits(), s.pose[i].to_bits());
            }
        }

        #[test]
        fn parsing_arbitrary_text_never_panics(text in ".{0,80}") {
            let _ = PoseSample::parse(&text);
        }
    }
}
