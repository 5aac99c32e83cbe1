//! The driver shared by the `kh4_reply` fuzz target (`fuzz/`) and its proptest driver:
//! arbitrary bytes become kh4server reply lines and encoder counts for [`parse_reply`]
//! and [`Odometry`]; a broken invariant panics. Not a stable API.

use robokey::fuzzing::Bytes;

use crate::khepera::{Odometry, PULSE_M, parse_reply};

/// The request letters the backend sends.
const REQUESTS: [char; 6] = ['R', 'D', 'E', 'I', 'U', 'V'];

/// Reply lines (arbitrary text, and well-formed replies with arbitrary numbers and
/// spacing) through [`parse_reply`], and encoder counts (from the parsed replies and
/// arbitrary ones, often at the ends of the `i64` and `i32` ranges) through
/// [`Odometry::update`].
///
/// # Panics
/// When the parser accepts a reply with the wrong number of numbers, misreads a
/// well-formed reply or rejects one without naming the request, or when the odometry
/// gives a non-finite pose or moves further in one update than two 32-bit counts allow.
pub fn kh4_reply(data: &[u8]) {
    let mut bytes = Bytes::new(data);
    let axle_length = [0.1047, 0.053, 1e-3, 10.0][usize::from(bytes.u8() % 4)];
    let mut odometry = Odometry::new(axle_length);
    let mut pose = odometry.update(bytes.i64(), bytes.i64());
    while !bytes.is_empty() {
        let request = REQUESTS[usize::from(bytes.u8()) % REQUESTS.len()];
        let expected = usize::from(bytes.u8() % 4);
        let counts = match bytes.u8() % 3 {
            0 => {
                let len = usize::from(bytes.u8() % 64);
                let line = String::from_utf8_lossy(bytes.take(len)).into_owned();
                parsed(request, &line, expected)
            }
            1 => {
                let count = usize::from(bytes.u8() % 4);
                let numbers: Vec<i64> = (0..count).map(|_| bytes.i64()).collect();
                let mut line = request.to_ascii_lowercase().to_string();
                for n in &numbers {
                    let pad = [""; 2].map(|_| if bytes.bool() { " " } else { "" });
                    line += &format!(",{}{n}{}", pad[0], pad[1]);
                }
                line += ["", "\n", "\r\n", "\r\n\r\n"][usize::from(bytes.u8() % 4)];
                let result = parsed(request, &line, expected);
                if count == expected {
                    assert_eq!(result.as_ref(), Some(&numbers), "{line:?}");
                } else {
                    assert!(result.is_none(), "{line:?} read as {expected} numbers");
                }
                result
            }
            _ => Some(vec![bytes.i64(), bytes.i64()]),
        };
        if let Some(&[left, right]) = counts.as_deref() {
            let next = odometry.update(left, right);
            assert!(
                next.iter().all(|v| v.is_finite()),
                "{next:?} from {left}, {right}"
            );
            let moved = (next.xy() - pose.xy()).norm();
            // 2³¹ pulses per wheel at most (1 µm for rounding at a far-away pose).
            let most = 2f64.powi(31) * PULSE_M + 1e-6;
            assert!(moved <= most, "moved {moved} m in one update");
            pose = next;
        }
    }
}

/// [`parse_reply`], checking that an accepted reply has the expected count and a rejected
/// one names its request.
fn parsed(request: char, line: &str, expected: usize) -> Option<Vec<i64>> {
    match parse_reply(request, line, expected) {
        Ok(numbers) => {
            assert_eq!(numbers.len(), expected, "{line:?}");
            Some(numbers)
        }
        Err(e) => {
            let text = e.to_string();
            assert!(text.contains(&format!("request {request}")), "{text}");
            None
        }
    }
}
