//! Pose streams (docs/sensors.md): what the world's sensors serve over TCP and what a
//! recorder writes to a file, in one format: a header line, then one line per sample, numbers
//! in the shortest decimal form that parses back to the same `f64`, so a reader sees exactly
//! the sampled values. A sensor sampled at the instants sends `step,x,y,theta` and a line
//! `k,x,y,θ` per sample instant `t_k` (m, m, rad); a camera filming between the instants
//! (docs/world.md) sends `time,x,y,theta` and a line `t,x,y,θ` per frame (t in s since the
//! session began).

use std::io::{BufRead, BufReader, BufWriter, ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use robokey::model::Pose;
use robokey::world::Frame;

use crate::error::NetError;

/// The header line of a stream or log of samples at the instants.
pub const HEADER: &str = "step,x,y,theta";

/// The header line of a stream or log of camera frames between the instants.
pub const FRAME_HEADER: &str = "time,x,y,theta";

/// Longest line a reader accepts (bytes, newline excluded); longer ones are skipped.
pub const MAX_LINE_BYTES: usize = 256;

/// Most samples a server keeps for clients that connect late (≈ 60 MB of lines); later
/// samples reach only the clients connected by then.
pub const MAX_BACKLOG_SAMPLES: usize = 1 << 20;

/// Most samples a log file may hold: a session is at most 10⁷ steps.
pub const MAX_LOG_SAMPLES: usize = 10_000_001;

/// How long a server waits for a slow client to take a line before dropping it.
const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// One line of a pose stream: a record with its header.
pub trait StreamRecord: Sized {
    /// The stream's header line.
    const HEADER: &'static str;
    /// Its line, newline included.
    fn line(&self) -> String;
    /// Parses a line (without its newline).
    ///
    /// # Errors
    /// What is wrong with it; never panics.
    fn parse(line: &str) -> Result<Self, &'static str>;
}

/// The pose after the first field of a line: three finite numbers, nothing more.
fn parse_pose(fields: &mut std::str::Split<'_, char>) -> Result<Pose, &'static str> {
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
    Ok(pose.into())
}

impl StreamRecord for Frame {
    const HEADER: &'static str = FRAME_HEADER;

    fn line(&self) -> String {
        let p = &self.pose;
        format!("{:?},{:?},{:?},{:?}\n", self.time, p.x, p.y, p.z)
    }

    fn parse(line: &str) -> Result<Self, &'static str> {
        let mut fields = line.trim_end_matches('\r').split(',');
        let time = fields
            .next()
            .and_then(|s| s.parse::<f64>().ok())
            .filter(|t| t.is_finite() && *t >= 0.0)
            .ok_or("the time is not a finite number of seconds ≥ 0")?;
        Ok(Self {
            time,
            pose: parse_pose(&mut fields)?,
        })
    }
}

/// One sample of a pose stream at the instants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSample {
    /// Step k: the sample instant `t_k = k·T`.
    pub step: u32,
    /// The measured pose (m, m, rad).
    pub pose: Pose,
}

impl StreamRecord for PoseSample {
    const HEADER: &'static str = HEADER;

    fn line(&self) -> String {
        let p = &self.pose;
        format!("{},{:?},{:?},{:?}\n", self.step, p.x, p.y, p.z)
    }

    fn parse(line: &str) -> Result<Self, &'static str> {
        let mut fields = line.trim_end_matches('\r').split(',');
        let step = fields
            .next()
            .and_then(|s| s.parse::<u32>().ok())
            .ok_or("the step is not a whole number")?;
        Ok(Self {
            step,
            pose: parse_pose(&mut fields)?,
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

/// Serves one pose stream of `R`s on TCP to any number of clients: each gets the header,
/// the session's samples so far, then every new one.
#[derive(Debug)]
pub struct PoseServer<R: StreamRecord> {
    address: SocketAddr,
    record: std::marker::PhantomData<fn(R)>,
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    acceptor: Option<JoinHandle<()>>,
}

impl<R: StreamRecord> PoseServer<R> {
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
            std::thread::spawn(move || accept(&listener, R::HEADER, &shared, &stop))
        };
        Ok(Self {
            address,
            record: std::marker::PhantomData,
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
    pub fn publish(&self, sample: &R) {
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

impl<R: StreamRecord> Drop for PoseServer<R> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(acceptor) = self.acceptor.take() {
            let _ = acceptor.join();
        }
        self.end_session();
    }
}

/// Accepts clients until `stop`, polling every 10 ms; each gets `header` first.
fn accept(listener: &TcpListener, header: &str, shared: &Mutex<Shared>, stop: &AtomicBool) {
    while !stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((mut client, _)) => {
                let ready = client.set_nonblocking(false).is_ok()
                    && client.set_write_timeout(Some(WRITE_TIMEOUT)).is_ok()
                    && client.set_nodelay(true).is_ok();
                let mut shared = shared.lock().unwrap_or_else(PoisonError::into_inner);
                let welcome = format!("{header}\n{}", shared.backlog);
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

    /// The next sample at the instants, waiting until `deadline` (the header and malformed
    /// lines are skipped).
    ///
    /// # Errors
    /// The socket fails.
    pub fn next_until(&mut self, deadline: Instant) -> Result<Reading, NetError> {
        loop {
            match self.next_line_until(deadline)? {
                Line::Text(text) if text == HEADER => {}
                Line::Text(text) => match PoseSample::parse(&text) {
                    Ok(sample) => return Ok(Reading::Sample(sample)),
                    Err(_) => self.malformed += 1,
                },
                Line::Nothing => return Ok(Reading::Nothing),
                Line::Ended => return Ok(Reading::Ended),
            }
        }
    }

    /// The next line (without its newline or carriage return), waiting until `deadline`;
    /// lines longer than [`MAX_LINE_BYTES`] are skipped and counted as malformed.
    ///
    /// # Errors
    /// The socket fails.
    pub fn next_line_until(&mut self, deadline: Instant) -> Result<Line, NetError> {
        let mut chunk = [0u8; 4096];
        loop {
            if let Some(end) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=end).collect();
                let text = std::str::from_utf8(&line[..end]).unwrap_or("");
                return Ok(Line::Text(text.trim_end_matches('\r').to_owned()));
            }
            if self.pending.len() > MAX_LINE_BYTES {
                self.pending.clear();
                self.skipping = true;
                self.malformed += 1;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(Line::Nothing);
            }
            self.stream
                .set_read_timeout(Some(left.max(Duration::from_micros(100))))
                .map_err(NetError::io("set the pose stream's timeout"))?;
            let n = match self.stream.read(&mut chunk) {
                Ok(0) => return Ok(Line::Ended),
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

/// A line a client read.
#[derive(Clone, Debug, PartialEq)]
pub enum Line {
    /// A line of text.
    Text(String),
    /// Nothing before the deadline.
    Nothing,
    /// The stream ended.
    Ended,
}

/// A camera's log: samples at the instants, or frames between them.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraLog {
    /// `step,x,y,theta` lines.
    Instants(Vec<PoseSample>),
    /// `time,x,y,theta` lines, in time order.
    Frames(Vec<Frame>),
}

impl CameraLog {
    /// How many samples or frames it holds.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Self::Instants(s) => s.len(),
            Self::Frames(f) => f.len(),
        }
    }

    /// Whether it holds none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Records the stream at `address` to a log file at `path` until the stream ends or
/// `stop()` says so (polled every 50 ms); returns the samples written. The file is created
/// new (an existing one is refused) and flushed as it grows; it starts with the stream's
/// header (samples at the instants, or frames between them), and a line that does not
/// parse as the header says is skipped.
///
/// # Errors
/// The stream cannot be reached, does not start with a pose stream's header, or the file
/// cannot be written.
pub fn record(address: SocketAddr, path: &Path, stop: impl Fn() -> bool) -> Result<u64, NetError> {
    let mut client = PoseStreamClient::connect(address, Duration::from_secs(5))?;
    let header = loop {
        if stop() {
            return Ok(0);
        }
        match client.next_line_until(Instant::now() + Duration::from_millis(50))? {
            Line::Text(text) if text == HEADER || text == FRAME_HEADER => break text,
            Line::Text(text) => {
                return Err(NetError::Usage(format!(
                    "{address} is not a pose stream: it starts with `{text}`, not `{HEADER}` \
                     or `{FRAME_HEADER}`"
                )));
            }
            Line::Nothing => {}
            Line::Ended => return Ok(0),
        }
    };
    let valid = |line: &str| match header.as_str() {
        HEADER => PoseSample::parse(line).map(|s| s.line()),
        _ => Frame::parse(line).map(|f| f.line()),
    };
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(NetError::io(format!("create {}", path.display())))?;
    let write_error = || NetError::io(format!("write {}", path.display()));
    let mut out = BufWriter::new(file);
    writeln!(out, "{header}").map_err(write_error())?;
    let mut written = 0;
    while !stop() {
        match client.next_line_until(Instant::now() + Duration::from_millis(50))? {
            Line::Text(text) => {
                if let Ok(line) = valid(&text) {
                    out.write_all(line.as_bytes()).map_err(write_error())?;
                    written += 1;
                }
            }
            Line::Nothing => out.flush().map_err(write_error())?,
            Line::Ended => break,
        }
    }
    out.flush().map_err(write_error())?;
    Ok(written)
}

/// Reads a pose log (e.g. Eve's camera, recorded by [`record`]): its samples or frames in
/// file order (frames must be in time order).
///
/// # Errors
/// The file cannot be read, lacks a header, holds a malformed line (named by its number),
/// frames out of time order, or more than [`MAX_LOG_SAMPLES`] lines.
pub fn read_log(path: &Path) -> Result<CameraLog, NetError> {
    let bad = |message: String| NetError::Capture {
        path: path.display().to_string(),
        message,
    };
    let file =
        std::fs::File::open(path).map_err(NetError::io(format!("open {}", path.display())))?;
    let mut lines =
        BufReader::new(file.take((MAX_LOG_SAMPLES as u64 + 1) * (MAX_LINE_BYTES as u64 + 1)))
            .lines();
    let frames = match lines.next() {
        Some(Ok(header)) if header.trim_end_matches('\r') == HEADER => false,
        Some(Ok(header)) if header.trim_end_matches('\r') == FRAME_HEADER => true,
        _ => {
            return Err(bad(format!(
                "not a pose log: the first line is neither `{HEADER}` nor `{FRAME_HEADER}`"
            )));
        }
    };
    let mut log = if frames {
        CameraLog::Frames(Vec::new())
    } else {
        CameraLog::Instants(Vec::new())
    };
    for (number, line) in lines.enumerate() {
        let line = line.map_err(NetError::io(format!("read {}", path.display())))?;
        let at = |why: &str| bad(format!("line {}: {why}", number + 2));
        if line.len() > MAX_LINE_BYTES {
            return Err(at("too long"));
        }
        if log.len() >= MAX_LOG_SAMPLES {
            return Err(bad(format!("more than {MAX_LOG_SAMPLES} samples")));
        }
        match &mut log {
            CameraLog::Instants(samples) => samples.push(PoseSample::parse(&line).map_err(at)?),
            CameraLog::Frames(frames) => {
                let frame = Frame::parse(&line).map_err(at)?;
                if frames.last().is_some_and(|last| frame.time <= last.time) {
                    return Err(at("a frame no later than the one before"));
                }
                frames.push(frame);
            }
        }
    }
    Ok(log)
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
        let server = PoseServer::<PoseSample>::bind("127.0.0.1:0".parse().unwrap()).unwrap();
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

    /// A camera filming between the instants: its frames recorded to a log read back exactly,
    /// in a log of frames; a log of frames out of time order is refused by line.
    #[test]
    fn a_frame_stream_records_to_a_log_of_frames() {
        let server = PoseServer::<Frame>::bind("127.0.0.1:0".parse().unwrap()).unwrap();
        let frames: Vec<Frame> = (0..5)
            .map(|m| Frame {
                time: 0.013 + f64::from(m) / 30.0,
                pose: Pose::new(0.1 * f64::from(m), -0.2, 1e-3),
            })
            .collect();
        server.publish(&frames[0]);
        let dir = std::env::temp_dir().join(format!("robokey-frames-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("camera.csv");
        let _ = std::fs::remove_file(&path);
        let (address, target) = (server.address(), path.clone());
        let recorder = std::thread::spawn(move || record(address, &target, || false));
        std::thread::sleep(Duration::from_millis(200));
        for frame in &frames[1..] {
            server.publish(frame);
        }
        std::thread::sleep(Duration::from_millis(100));
        server.end_session();
        assert_eq!(recorder.join().unwrap().unwrap(), 5);
        assert_eq!(read_log(&path).unwrap(), CameraLog::Frames(frames.clone()));
        let text = format!("{FRAME_HEADER}\n{}{}", frames[1].line(), frames[0].line());
        std::fs::write(&path, text).unwrap();
        let error = read_log(&path).unwrap_err().to_string();
        assert!(
            error.contains("line 3") && error.contains("no later"),
            "{error}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    proptest! {
        #[test]
        fn frame_lines_round_trip_exactly(time in 0.0..1e7f64, x in -1e3..1e3f64, y in -1e3..1e3f64, z in -1e3..1e3f64) {
            let f = Frame { time, pose: Pose::new(x, y, z) };
            let line = f.line();
            prop_assert!(line.len() <= MAX_LINE_BYTES);
            let back = Frame::parse(line.trim_end()).unwrap();
            prop_assert_eq!(back.time.to_bits(), time.to_bits());
            for i in 0..3 {
                prop_assert_eq!(back.pose[i].to_bits(), f.pose[i].to_bits());
            }
        }

        #[test]
        fn parsing_arbitrary_frame_text_never_panics(text in ".{0,80}") {
            let _ = Frame::parse(&text);
        }

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
