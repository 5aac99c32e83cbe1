//! The byte stream to kh4server: a TCP connection or a serial device.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use crate::error::NetError;

/// A line-oriented connection to kh4server.
#[derive(Debug)]
pub struct Link {
    name: String,
    reader: BufReader<Box<dyn ReadWrite>>,
}

/// A readable and writable stream.
trait ReadWrite: Read + Write + Send + std::fmt::Debug {
    fn writer(&mut self) -> &mut dyn Write;
}

impl ReadWrite for TcpStream {
    fn writer(&mut self) -> &mut dyn Write {
        self
    }
}

impl ReadWrite for File {
    fn writer(&mut self) -> &mut dyn Write {
        self
    }
}

impl Link {
    /// Opens `tcp:HOST:PORT` or a device path (e.g. `/dev/rfcomm0`, configured beforehand
    /// with `stty -F DEV 115200 raw`). TCP replies time out after `timeout`; a serial
    /// device blocks.
    ///
    /// # Errors
    /// The connection or device cannot be opened.
    pub fn open(spec: &str, timeout: Duration) -> Result<Self, NetError> {
        let stream: Box<dyn ReadWrite> = if let Some(address) = spec.strip_prefix("tcp:") {
            let stream = TcpStream::connect(address)
                .map_err(NetError::io(format!("connect to kh4server at {address}")))?;
            stream
                .set_read_timeout(Some(timeout))
                .map_err(NetError::io("set kh4 read timeout"))?;
            stream
                .set_nodelay(true)
                .map_err(NetError::io("set TCP_NODELAY"))?;
            Box::new(stream)
        } else {
            let device = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .open(spec)
                .map_err(NetError::io(format!("open kh4 device {spec}")))?;
            Box::new(device)
        };
        Ok(Self {
            name: spec.to_owned(),
            reader: BufReader::new(stream),
        })
    }

    /// Sends one request line and returns the reply line.
    ///
    /// # Errors
    /// The link fails, times out or closes.
    pub fn request(&mut self, line: &str) -> Result<String, NetError> {
        let context = || format!("kh4 {}: request {:?}", self.name, line.trim_end());
        let writer = self.reader.get_mut().writer();
        writer
            .write_all(line.as_bytes())
            .and_then(|()| writer.flush())
            .map_err(NetError::io(context()))?;
        let mut reply = String::new();
        match self.reader.read_line(&mut reply) {
            Ok(0) => Err(NetError::Kh4(format!(
                "{}: the connection closed",
                context()
            ))),
            Ok(_) => Ok(reply),
            Err(e) => Err(NetError::io(context())(e)),
        }
    }
}
