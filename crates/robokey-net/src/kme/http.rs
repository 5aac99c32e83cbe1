//! HTTP/1.1 for the key server, bounded before any work: a request head of at most
//! [`MAX_HEAD_BYTES`] in at most [`MAX_HEADERS`] header lines (parsed by `httparse`), a body
//! of at most [`MAX_BODY_BYTES`] announced by `Content-Length` (no chunked bodies), one
//! request per connection (every response says `Connection: close`). Whatever the bytes,
//! reading ends in a request, a refusal to answer with 400, or an I/O error — never a panic.

use std::io::{Read, Write};

use zeroize::Zeroizing;

/// Longest request head (bytes): the request line and the header lines.
pub const MAX_HEAD_BYTES: usize = 8 * 1024;
/// Most header lines.
pub const MAX_HEADERS: usize = 32;
/// Longest body (bytes): 128 key IDs take about 7 kB.
pub const MAX_BODY_BYTES: usize = 64 * 1024;

/// A request, read whole.
#[derive(Debug, PartialEq, Eq)]
pub struct Request {
    /// `GET`, `POST`, …
    pub method: String,
    /// The request target: path and query.
    pub target: String,
    /// The body (empty without `Content-Length`).
    pub body: Vec<u8>,
}

/// Why no request was read.
#[derive(Debug)]
pub enum ReadError {
    /// The bytes are not a request this server takes: answer 400 with the message.
    Refused(String),
    /// The connection failed, timed out or ended early: nothing to answer.
    Io(std::io::Error),
}

/// A response: a status and a JSON body (zeroized when dropped: it may carry keys).
#[derive(Debug)]
pub struct Response {
    /// 200, 400, 401 or 503.
    pub status: u16,
    /// The JSON body.
    pub body: Zeroizing<Vec<u8>>,
}

/// Reads one request from `stream`. A client that announces `Expect: 100-continue` gets the
/// interim `100 Continue` once its `Content-Length` is within bounds.
///
/// # Errors
/// [`ReadError::Refused`] for what is not a bounded HTTP/1.x request with a known length;
/// [`ReadError::Io`] when the stream fails or ends first.
pub fn read_request<S: Read + Write>(stream: &mut S) -> Result<Request, ReadError> {
    let mut buffer = Vec::with_capacity(1024);
    let (head_length, method, target, length, expect_continue) = loop {
        let mut chunk = [0_u8; 1024];
        let room = (MAX_HEAD_BYTES + 1 - buffer.len()).min(chunk.len());
        let n = stream.read(&mut chunk[..room]).map_err(ReadError::Io)?;
        if n == 0 {
            return Err(ReadError::Io(std::io::ErrorKind::UnexpectedEof.into()));
        }
        buffer.extend_from_slice(&chunk[..n]);
        let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
        let mut request = httparse::Request::new(&mut headers);
        match request.parse(&buffer) {
            Ok(httparse::Status::Complete(head_length)) => {
                let (length, expect_continue) = body_length(request.headers)?;
                break (
                    head_length,
                    request.method.unwrap_or_default().to_owned(),
                    request.path.unwrap_or_default().to_owned(),
                    length,
                    expect_continue,
                );
            }
            Ok(httparse::Status::Partial) if buffer.len() > MAX_HEAD_BYTES => {
                return Err(ReadError::Refused(format!(
                    "the request head exceeds {MAX_HEAD_BYTES} bytes"
                )));
            }
            Ok(httparse::Status::Partial) => {}
            Err(httparse::Error::TooManyHeaders) => {
                return Err(ReadError::Refused(format!(
                    "more than {MAX_HEADERS} header lines"
                )));
            }
            Err(error) => {
                return Err(ReadError::Refused(format!(
                    "not an HTTP/1.x request: {error}"
                )));
            }
        }
    };
    if expect_continue {
        stream
            .write_all(b"HTTP/1.1 100 Continue\r\n\r\n")
            .and_then(|()| stream.flush())
            .map_err(ReadError::Io)?;
    }
    let mut body = buffer.split_off(head_length);
    body.truncate(length);
    if body.len() < length {
        let missing = length - body.len();
        let start = body.len();
        body.resize(length, 0);
        stream
            .read_exact(&mut body[start..start + missing])
            .map_err(ReadError::Io)?;
    }
    Ok(Request {
        method,
        target,
        body,
    })
}

/// The body's length from the headers, and whether the client waits for `100 Continue`.
fn body_length(headers: &[httparse::Header<'_>]) -> Result<(usize, bool), ReadError> {
    let mut length = None;
    let mut expect_continue = false;
    for header in headers {
        if header.name.eq_ignore_ascii_case("transfer-encoding") {
            return Err(ReadError::Refused(
                "chunked or encoded bodies are not taken: send Content-Length".into(),
            ));
        }
        if header.name.eq_ignore_ascii_case("expect") {
            expect_continue = header.value.eq_ignore_ascii_case(b"100-continue");
        }
        if header.name.eq_ignore_ascii_case("content-length") {
            let value = std::str::from_utf8(header.value)
                .ok()
                .and_then(|v| v.trim().parse::<usize>().ok())
                .ok_or_else(|| ReadError::Refused("Content-Length is not a number".into()))?;
            if length.is_some_and(|l| l != value) {
                return Err(ReadError::Refused("two different Content-Lengths".into()));
            }
            if value > MAX_BODY_BYTES {
                return Err(ReadError::Refused(format!(
                    "a body of {value} bytes exceeds {MAX_BODY_BYTES}"
                )));
            }
            length = Some(value);
        }
    }
    Ok((
        length.unwrap_or(0),
        expect_continue && length.unwrap_or(0) > 0,
    ))
}

/// Writes `response` with its headers, then flushes.
///
/// # Errors
/// The stream fails.
pub fn write_response<S: Write>(stream: &mut S, response: &Response) -> std::io::Result<()> {
    let reason = match response.status {
        200 => "OK",
        400 => "Bad Request",
        401 => "Unauthorized",
        _ => "Service Unavailable",
    };
    let mut bytes = Zeroizing::new(Vec::with_capacity(response.body.len() + 160));
    bytes.extend_from_slice(
        format!(
            "HTTP/1.1 {} {reason}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\
             Cache-Control: no-store\r\nConnection: close\r\n\r\n",
            response.status,
            response.body.len()
        )
        .as_bytes(),
    );
    bytes.extend_from_slice(&response.body);
    stream.write_all(&bytes)?;
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A connection: the bytes a client sent, and what the server wrote back.
    struct Wire {
        incoming: std::io::Cursor<Vec<u8>>,
        written: Vec<u8>,
    }

    impl Wire {
        fn new(bytes: &[u8]) -> Self {
            Self {
                incoming: std::io::Cursor::new(bytes.to_vec()),
                written: Vec::new(),
            }
        }
    }

    impl Read for Wire {
        fn read(&mut self, buffer: &mut [u8]) -> std::io::Result<usize> {
            // Three bytes at a time: a request arrives in pieces.
            let n = buffer.len().min(3);
            self.incoming.read(&mut buffer[..n])
        }
    }

    impl Write for Wire {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            self.written.write(bytes)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    fn refused(bytes: &[u8]) -> String {
        match read_request(&mut Wire::new(bytes)) {
            Err(ReadError::Refused(message)) => message,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn requests_are_read_whole_in_pieces() {
        let request = read_request(&mut Wire::new(
            b"GET /api/v1/keys/robot/status HTTP/1.1\r\nHost: x\r\n\r\n",
        ))
        .unwrap();
        assert_eq!(request.method, "GET");
        assert_eq!(request.target, "/api/v1/keys/robot/status");
        assert!(request.body.is_empty());
        let mut wire = Wire::new(
            b"POST /k HTTP/1.1\r\nContent-Length: 12\r\nExpect: 100-continue\r\n\r\n{\"number\":2}",
        );
        let request = read_request(&mut wire).unwrap();
        assert_eq!(request.body, b"{\"number\":2}");
        assert_eq!(wire.written, b"HTTP/1.1 100 Continue\r\n\r\n");
    }

    #[test]
    fn what_is_not_a_bounded_request_is_refused_or_an_early_end() {
        let long_head = format!("GET /{} HTTP/1.1\r\n\r\n", "a".repeat(MAX_HEAD_BYTES));
        assert!(refused(long_head.as_bytes()).contains("exceeds 8192"));
        let headers: String = (0..40).map(|i| format!("X-{i}: 1\r\n")).collect();
        let many = format!("GET / HTTP/1.1\r\n{headers}\r\n");
        assert!(refused(many.as_bytes()).contains("more than 32"));
        let big = format!(
            "POST / HTTP/1.1\r\nContent-Length: {}\r\n\r\n",
            MAX_BODY_BYTES + 1
        );
        assert!(refused(big.as_bytes()).contains("exceeds 65536"));
        assert!(
            refused(b"POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n").contains("chunked")
        );
        assert!(refused(b"POST / HTTP/1.1\r\nContent-Length: -1\r\n\r\n").contains("not a number"));
        assert!(
            refused(b"POST / HTTP/1.1\r\nContent-Length: 1\r\nContent-Length: 2\r\n\r\n")
                .contains("two different")
        );
        assert!(refused(b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03").contains("not an HTTP"));
        for early in [
            &b""[..],
            b"GET / HTTP/1.1\r\n",
            b"POST / HTTP/1.1\r\nContent-Length: 9\r\n\r\n{}",
        ] {
            assert!(
                matches!(read_request(&mut Wire::new(early)), Err(ReadError::Io(_))),
                "{early:?}"
            );
        }
    }

    #[test]
    fn responses_carry_their_length_and_close() {
        let mut wire = Wire::new(b"");
        write_response(
            &mut wire,
            &Response {
                status: 401,
                body: Zeroizing::new(b"{}".to_vec()),
            },
        )
        .unwrap();
        let text = String::from_utf8(wire.written).unwrap();
        assert!(text.starts_with("HTTP/1.1 401 Unauthorized\r\n"), "{text}");
        assert!(text.contains("Content-Length: 2\r\n") && text.contains("Connection: close"));
        assert!(text.ends_with("\r\n\r\n{}"), "{text}");
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, rng_seed: proptest::test_runner::RngSeed::Fixed(29), ..ProptestConfig::default() })]
        /// Any bytes, and any bytes after a valid request line: a request, a refusal or an
        /// early end, never a panic, and never a body past the bound.
        #[test]
        fn no_bytes_make_reading_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300), tail in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = read_request(&mut Wire::new(&bytes));
            let mut framed = b"POST /api/v1/keys/a/dec_keys HTTP/1.1\r\n".to_vec();
            framed.extend_from_slice(&tail);
            if let Ok(request) = read_request(&mut Wire::new(&framed)) {
                prop_assert!(request.body.len() <= MAX_BODY_BYTES);
            }
        }
    }
}
