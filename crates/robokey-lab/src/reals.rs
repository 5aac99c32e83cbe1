//! Reals in JSON that robokey reads back: serde_json writes NaN and ±∞ as `null`, so a field
//! that may hold one reads `null` back as the value it stands for there.

use serde::{Deserialize, Deserializer};

/// A real that is NaN where undefined (e.g. a test that could not run).
///
/// # Errors
/// Neither a number nor `null`.
pub fn nan_if_null<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN))
}

/// An upper bound that is +∞ where open.
///
/// # Errors
/// Neither a number nor `null`.
pub fn infinity_if_null<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::INFINITY))
}

/// A value with its interval, each NaN where undefined (an empty sample).
///
/// # Errors
/// Not an array of three numbers or `null`s.
pub fn nans_if_null<'de, D: Deserializer<'de>>(deserializer: D) -> Result<[f64; 3], D::Error> {
    Ok(<[Option<f64>; 3]>::deserialize(deserializer)?.map(|x| x.unwrap_or(f64::NAN)))
}

#[cfg(test)]
mod tests {
    #[derive(serde::Serialize, serde::Deserialize)]
    struct Figures {
        #[serde(deserialize_with = "super::nan_if_null")]
        p: f64,
        #[serde(deserialize_with = "super::infinity_if_null")]
        to: f64,
        #[serde(deserialize_with = "super::nans_if_null")]
        interval: [f64; 3],
    }

    #[test]
    fn non_finite_reals_read_back_as_written() {
        let figures = Figures {
            p: f64::NAN,
            to: f64::INFINITY,
            interval: [0.5, f64::NAN, 0.75],
        };
        let json = serde_json::to_string(&figures).unwrap();
        assert_eq!(json, r#"{"p":null,"to":null,"interval":[0.5,null,0.75]}"#);
        let back: Figures = serde_json::from_str(&json).unwrap();
        assert!(back.p.is_nan() && back.to == f64::INFINITY);
        assert!(back.interval[0] == 0.5 && back.interval[1].is_nan());
        assert_eq!(serde_json::to_string(&back).unwrap(), json);
    }
}
