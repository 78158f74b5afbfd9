//! Numbers that may be NaN (an unmeasured value): JSON has no NaN, serde_json
//! writes it as `null`; these read `null` back as NaN.

use serde::{Deserialize, Deserializer};

/// An `f64` field written as a number or `null` (NaN).
pub(crate) fn f64_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// A list of `f64` whose elements may be `null` (NaN).
pub(crate) fn f64s_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    Ok(Vec::<Option<f64>>::deserialize(d)?
        .into_iter()
        .map(|v| v.unwrap_or(f64::NAN))
        .collect())
}

/// Three `f64` (x, y, z) whose elements may be `null` (NaN).
pub(crate) fn xyz_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    let v = <[Option<f64>; 3]>::deserialize(d)?;
    Ok(v.map(|x| x.unwrap_or(f64::NAN)))
}

/// An optional three `f64` whose elements may be `null` (NaN).
pub(crate) fn opt_xyz_or_nan<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Option<[f64; 3]>, D::Error> {
    let v = Option::<[Option<f64>; 3]>::deserialize(d)?;
    Ok(v.map(|v| v.map(|x| x.unwrap_or(f64::NAN))))
}
