//! Angles as users write them: a number of radians or a short expression with π.
//!
//! Design files are easier to read with `"pi/2"` than with `1.5707963267948966`. An [`Angle`]
//! deserialises from a TOML number or from a string of the form `[sign][number][*]pi[/number]`
//! or a plain number (`"pi/2"`, `"-pi/6"`, `"3*pi/4"`, `"2pi"`, `"0.5"`). Nothing else is
//! accepted, so a typo is an error rather than a silent zero; nor is an angle beyond
//! [`crate::limits::MAX_ANGLE_RAD`].

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// An angle in radians.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Angle(pub f64);

impl Angle {
    /// Parses `[sign][number][*]pi[/number]` or a plain number.
    pub fn parse(text: &str) -> Result<f64, String> {
        let t: String = text.chars().filter(|c| !c.is_whitespace()).collect::<String>().to_lowercase();
        let bad = || {
            format!("`{text}` is not an angle: write radians as a number or an expression like \"pi/2\", \"-3*pi/4\"")
        };
        if t.is_empty() {
            return Err(bad());
        }
        let (sign, rest) = match t.strip_prefix('-') {
            Some(r) => (-1.0, r),
            None => (1.0, t.strip_prefix('+').unwrap_or(&t)),
        };
        let t = rest.replace('π', "pi");
        let value = if let Some(pos) = t.find("pi") {
            let (before, after) = (&t[..pos], &t[pos + 2..]);
            let factor = match before.strip_suffix('*').unwrap_or(before) {
                "" => 1.0,
                f => f.parse::<f64>().map_err(|_| bad())?,
            };
            let divisor = match after {
                "" => 1.0,
                a => a.strip_prefix('/').ok_or_else(bad)?.parse::<f64>().map_err(|_| bad())?,
            };
            if divisor == 0.0 {
                return Err(bad());
            }
            factor * std::f64::consts::PI / divisor
        } else {
            t.parse::<f64>().map_err(|_| bad())?
        };
        if !value.is_finite() {
            return Err(format!("`{text}` is not a finite angle"));
        }
        Ok(sign * value)
    }
}

impl<'de> Deserialize<'de> for Angle {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Num(f64),
            Int(i64),
            Text(String),
        }
        let v = match Raw::deserialize(d)
            .map_err(|_| serde::de::Error::custom("expected an angle: a number of radians or a string like \"pi/2\""))?
        {
            Raw::Num(x) => x,
            Raw::Int(i) => i as f64,
            Raw::Text(s) => Angle::parse(&s).map_err(serde::de::Error::custom)?,
        };
        // TOML has `nan` and `inf`: an angle must be a finite number, as written in text or not,
        // and one no arm turns through (see `limits::MAX_ANGLE_RAD`).
        if !v.is_finite() {
            return Err(serde::de::Error::custom(format!("`{v}` is not a finite angle")));
        }
        crate::limits::within(v, crate::limits::MAX_ANGLE_RAD, " rad")
            .map_err(|e| serde::de::Error::custom(format!("the angle {e}")))?;
        Ok(Angle(v))
    }
}

impl Serialize for Angle {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(self.0)
    }
}

/// `x` in scientific notation with `digits` decimals for messages and tables, reading as people
/// write it: exact zero is `0` (not `0.000e0`), and no `-0`.
pub fn sci(x: f64, digits: usize) -> String {
    if x == 0.0 { "0".to_string() } else { format!("{x:.digits$e}") }
}

/// A unit as people read it (`N·m/rad³`); `bom.csv` and `compare.csv` keep the ASCII spelling
/// (`N*m/rad^3`) that every CSV reader takes.
pub(crate) fn shown(unit: &str) -> String {
    unit.replace('*', "·").replace("^3", "³")
}

/// A residual angle in degrees for tables and legends: four decimals, or scientific notation
/// below 0.001° (the exact potential's 1e-7° would read `0.0000°`, as if it were nothing).
pub fn deg(x: f64) -> String {
    if x != 0.0 && x.abs() < 1e-3 { format!("{}°", sci(x, 2)) } else { format!("{x:.4}°") }
}

#[cfg(test)]
mod tests {
    #[test]
    fn tiny_angles_keep_their_digits() {
        assert_eq!(super::deg(0.38531), "0.3853°");
        assert_eq!(super::deg(1.234e-7), "1.23e-7°");
        assert_eq!(super::deg(0.0), "0.0000°");
    }

    #[test]
    fn sci_reads_as_written() {
        assert_eq!(super::sci(0.0, 3), "0");
        assert_eq!(super::sci(-0.0, 3), "0");
        assert_eq!(super::sci(4.45e-4, 2), "4.45e-4");
        assert_eq!(super::sci(-12345.0, 1), "-1.2e4");
    }

    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn parses_expressions() {
        for (text, value) in [
            ("pi/2", PI / 2.0),
            ("-pi/6", -PI / 6.0),
            ("3*pi/4", 0.75 * PI),
            ("2pi", 2.0 * PI),
            ("π", PI),
            ("0.25", 0.25),
            (" - 1.5 ", -1.5),
            ("PI", PI),
        ] {
            assert!((Angle::parse(text).unwrap() - value).abs() < 1e-15, "{text}");
        }
        for bad in ["", "pie", "pi/0", "pi/x", "x", "1e999", "pi*2/"] {
            assert!(Angle::parse(bad).is_err(), "{bad}");
        }
    }
}
