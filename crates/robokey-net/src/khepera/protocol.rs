//! kh4server requests and replies, unit conversions, and encoder odometry (docs/protocol.md, "The Khepera IV backend").

use robokey::model::Pose;

use crate::error::NetError;

/// One speed unit (m/s of wheel rim speed).
pub const SPEED_UNIT_M_S: f64 = 0.6781e-3;
/// One encoder pulse (m of wheel travel): 0.13194 m per 19456 pulses.
pub const PULSE_M: f64 = 0.13194 / 19_456.0;
/// Largest speed the robot accepts (units).
pub const MAX_UNITS: i64 = 1200;

/// Wheel speed (rad/s) to kh4server speed units, rounded and clamped to ±1200.
#[must_use]
pub fn speed_units(omega: f64, wheel_radius: f64) -> i64 {
    let units = (omega * wheel_radius / SPEED_UNIT_M_S).round();
    if units.is_nan() {
        0
    } else {
        (units as i64).clamp(-MAX_UNITS, MAX_UNITS)
    }
}

/// `D,<left>,<right>\n`: **left wheel first**.
#[must_use]
pub fn set_speed_request(left: i64, right: i64) -> String {
    format!("D,{left},{right}\n")
}

/// Parses a reply `letter[,n…]` to request `letter` (upper case), returning its numbers.
///
/// # Errors
/// `$` (the server's error reply), a wrong letter, or a malformed number.
pub fn parse_reply(
    request: char,
    reply: &str,
    expected_numbers: usize,
) -> Result<Vec<i64>, NetError> {
    let line = reply.trim_end_matches(['\r', '\n']);
    let bad = |why: &str| NetError::Kh4(format!("request {request}: reply {line:?}: {why}"));
    if line == "$" {
        return Err(bad("the robot answered with an error ($)"));
    }
    let mut parts = line.split(',');
    if parts.next() != Some(&request.to_ascii_lowercase().to_string()) {
        return Err(bad("unexpected reply"));
    }
    let numbers: Vec<i64> = parts
        .map(|p| p.trim().parse::<i64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad("not a number"))?;
    if numbers.len() != expected_numbers {
        return Err(bad(&format!("expected {expected_numbers} numbers")));
    }
    Ok(numbers)
}

/// Midpoint odometry from encoder pulses (docs/protocol.md); θ is never wrapped.
///
/// The Khepera's encoder counters are 32-bit signed registers on the robot: a count wraps
/// from `i32::MAX` to `i32::MIN` after about 14.6 km of wheel travel. A wheel's travel
/// between two reads is therefore the difference of the counts modulo 2³² (wrapping
/// `i32`), which is exact across a wrap as long as the wheel turns fewer than 2³¹ pulses
/// between reads (at full speed, about five hours). A reported count outside the `i32`
/// range is taken modulo 2³², as the register holds it. Each update thus moves each wheel
/// by at most 14.6 km, and the pose stays finite for any counts and a positive axle length.
#[derive(Clone, Debug, PartialEq)]
pub struct Odometry {
    axle_length: f64,
    last: Option<(i64, i64)>,
    pose: Pose,
}

impl Odometry {
    /// Odometry at the origin for axle length `D` (m).
    #[must_use]
    pub fn new(axle_length: f64) -> Self {
        Self {
            axle_length,
            last: None,
            pose: Pose::zeros(),
        }
    }

    /// Updates with the encoder counts (left, right); the first call sets the reference.
    pub fn update(&mut self, left: i64, right: i64) -> Pose {
        if let Some((last_left, last_right)) = self.last {
            let ds_left = f64::from(pulses(left, last_left)) * PULSE_M;
            let ds_right = f64::from(pulses(right, last_right)) * PULSE_M;
            let dtheta = (ds_right - ds_left) / self.axle_length;
            let mid = self.pose.z + dtheta / 2.0;
            let ds = (ds_left + ds_right) / 2.0;
            self.pose += Pose::new(ds * mid.cos(), ds * mid.sin(), dtheta);
        }
        self.last = Some((left, right));
        self.pose
    }
}

/// Pulses from count `before` to count `now` of a 32-bit encoder register (see
/// [`Odometry`]).
fn pulses(now: i64, before: i64) -> i32 {
    (now as i32).wrapping_sub(before as i32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn units_are_rounded_clamped_and_left_first() {
        // 4 rad/s · 0.021 m = 84 mm/s = 123.9 units.
        assert_eq!(speed_units(4.0, 0.021), 124);
        assert_eq!(speed_units(-400.0, 0.021), -1200);
        assert_eq!(speed_units(f64::NAN, 0.021), 0);
        assert_eq!(set_speed_request(-5, 7), "D,-5,7\n");
    }

    #[test]
    fn odometry_drives_straight_and_spins() {
        let mut odo = Odometry::new(0.1047);
        odo.update(100, 200);
        let pose = odo.update(100 + 19_456, 200 + 19_456);
        assert!((pose - Pose::new(0.13194, 0.0, 0.0)).norm() < 1e-12);
        // Spin in place: the right wheel travels +s, the left −s: Δθ = 2s/D.
        let s = 1000.0 * PULSE_M;
        let pose = odo.update(100 + 19_456 - 1000, 200 + 19_456 + 1000);
        assert!((pose.z - 2.0 * s / 0.1047).abs() < 1e-12);
        assert!((pose.x - 0.13194).abs() < 1e-12);
    }

    /// Found by the `kh4_reply` fuzz target: `left - last_left` overflowed (a panic in
    /// debug builds) on counts such as `i64::MAX` then `i64::MIN`; and a wrap of the 32-bit
    /// register read as a jump of 2³² pulses (29 km) backwards.
    #[test]
    fn encoder_counts_wrap_as_32_bit_registers() {
        let mut odo = Odometry::new(0.1047);
        odo.update(i64::from(i32::MAX) - 99, i64::from(i32::MAX) - 99);
        // 100 pulses forward on both wheels, across the wrap of the register.
        let pose = odo.update(i64::from(i32::MIN), i64::from(i32::MIN));
        assert!((pose - Pose::new(100.0 * PULSE_M, 0.0, 0.0)).norm() < 1e-15);
        // Counts outside the i32 range are taken modulo 2³²: i64::MAX ≡ −1, i64::MIN ≡ 0.
        let mut odo = Odometry::new(0.1047);
        odo.update(i64::MAX, i64::MAX);
        let pose = odo.update(i64::MIN, i64::MIN);
        assert!((pose - Pose::new(PULSE_M, 0.0, 0.0)).norm() < 1e-15);
        // The largest jumps one update can report keep the pose finite.
        for (left, right) in [
            (i64::MIN, i64::MAX),
            (0, i64::from(i32::MIN)),
            (i64::MAX, 0),
        ] {
            assert!(odo.update(left, right).iter().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn replies_parse_or_fail_with_a_named_error() {
        assert_eq!(parse_reply('R', "r,12,-3\r\n", 2).unwrap(), vec![12, -3]);
        assert_eq!(parse_reply('D', "d\r\n", 0).unwrap(), Vec::<i64>::new());
        for bad in ["$\r\n", "r,abc,1", "r,1", "", "x,1,2"] {
            let err = parse_reply('R', bad, 2).unwrap_err().to_string();
            assert!(err.contains("request R"), "{err}");
        }
    }

    proptest! {
        #[test]
        fn arbitrary_replies_never_panic(reply in ".{0,40}") {
            let _ = parse_reply('R', &reply, 2);
        }
    }
}
