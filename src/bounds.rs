//! Allowed ranges of parameters, and how error messages print numbers.
//!
//! Every size-like or work-like parameter a user can set (in a `--config`
//! file or a [`crate::backend::FrameRequest`]) has a documented lower and
//! upper bound, so that the work and memory of a frame stay bounded. The
//! trackers' `validate` functions check their parameters against an
//! [`Interval`] (reals) or [`check_count`] (integers); the error names the
//! parameter and states the allowed range, with numbers shortened by
//! [`short_number`] so that a value of 300 digits prints as `1.0e300`.

use std::fmt;

use crate::{Error, Result};

/// Magnitudes from which [`short_number`] switches to scientific notation.
const SCIENTIFIC_ABOVE: f64 = 1e9;
/// Magnitudes below which (other than 0) [`short_number`] switches to
/// scientific notation.
const SCIENTIFIC_BELOW: f64 = 1e-4;
/// Digit runs longer than this are shortened by [`shorten_digit_runs`].
const MAX_DIGIT_RUN: usize = 12;

/// A message on one line: its lines trimmed, the empty ones dropped, the
/// rest joined with `; ` (an error of a library that spans lines, for a
/// one-line error or a summary line).
#[must_use]
pub fn one_line(message: &str) -> String {
    message.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("; ")
}

/// `n` and the noun for it: `1 joint`, `2 joints`.
#[must_use]
pub fn counted(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// `v` for a one-line message: as Rust prints it when it is moderate
/// (`12.5`, `0.001`, `NaN`, `inf`), in scientific notation with a few
/// significant digits otherwise (`1.0e300`, `-2.5e-12`), never longer than
/// a dozen or so characters.
#[must_use]
pub fn short_number(v: f64) -> String {
    let a = v.abs();
    if !v.is_finite() || a == 0.0 || (SCIENTIFIC_BELOW..SCIENTIFIC_ABOVE).contains(&a) {
        let s = format!("{v}");
        if s.len() <= MAX_DIGIT_RUN + 2 {
            return s;
        }
        // Many decimals of a moderate value: four significant digits suffice.
        return format!("{}", (v * 1e4).round() / 1e4);
    }
    let s = format!("{v:.3e}");
    // `1.000e300` → `1.0e300`, `2.500e-12` → `2.5e-12`.
    match s.split_once('e') {
        Some((mantissa, exponent)) => {
            let mantissa = mantissa.trim_end_matches('0');
            let mantissa = if mantissa.ends_with('.') { format!("{mantissa}0") } else { mantissa.to_string() };
            format!("{mantissa}e{exponent}")
        }
        None => s,
    }
}

/// `text` with every run of more than a dozen digits (with its sign,
/// decimal point and fraction) replaced by [`short_number`] of its value, so
/// that a message quoting what the user wrote stays one short line.
#[must_use]
pub fn shorten_digit_runs(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len().min(1024));
    let mut i = 0;
    while i < bytes.len() {
        if !bytes[i].is_ascii_digit() {
            // Copy one whole character (the text may hold multi-byte ones).
            let len = text[i..].chars().next().map_or(1, char::len_utf8);
            out.push_str(&text[i..i + len]);
            i += len;
            continue;
        }
        let start = i;
        while i < bytes.len() && (bytes[i].is_ascii_digit() || bytes[i] == b'_') {
            i += 1;
        }
        if i + 1 < bytes.len() && bytes[i] == b'.' && bytes[i + 1].is_ascii_digit() {
            i += 1;
            while i < bytes.len() && (bytes[i].is_ascii_digit() || bytes[i] == b'_') {
                i += 1;
            }
        }
        let run = &text[start..i];
        let digits = run.bytes().filter(u8::is_ascii_digit).count();
        if digits > MAX_DIGIT_RUN {
            match run.replace('_', "").parse::<f64>() {
                Ok(v) => out.push_str(&short_number(v)),
                Err(_) => out.push_str(&format!("{}…", &run[..MAX_DIGIT_RUN])),
            }
        } else {
            out.push_str(run);
        }
    }
    out
}

/// An interval of allowed real values, each end open or closed; NaN is
/// never inside. Prints as `(0, 1000]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Whether `lo` itself is allowed.
    pub lo_closed: bool,
    /// Upper end (`f64::INFINITY` allows any finite value and infinity
    /// itself when `hi_closed`).
    pub hi: f64,
    /// Whether `hi` itself is allowed.
    pub hi_closed: bool,
}

impl Interval {
    /// `[lo, hi]`.
    #[must_use]
    pub const fn closed(lo: f64, hi: f64) -> Self {
        Self { lo, lo_closed: true, hi, hi_closed: true }
    }

    /// `(lo, hi]`: e.g. `(0, MAX]` for a positive parameter.
    #[must_use]
    pub const fn open_closed(lo: f64, hi: f64) -> Self {
        Self { lo, lo_closed: false, hi, hi_closed: true }
    }

    /// `(lo, hi)`.
    #[must_use]
    pub const fn open(lo: f64, hi: f64) -> Self {
        Self { lo, lo_closed: false, hi, hi_closed: false }
    }

    /// Whether `v` lies in the interval (never for NaN).
    #[must_use]
    pub fn contains(&self, v: f64) -> bool {
        let above = if self.lo_closed { v >= self.lo } else { v > self.lo };
        let below = if self.hi_closed { v <= self.hi } else { v < self.hi };
        above && below
    }

    /// `Ok` when `v` lies in the interval; otherwise an
    /// [`Error::Parameter`] `"{who}: {name} must be in {self}{unit}, got {v}"`
    /// (`unit` with its leading space, e.g. `" px"`, or empty).
    pub fn check(&self, who: &str, name: &str, v: f64, unit: &str) -> Result<()> {
        if self.contains(v) {
            Ok(())
        } else {
            // A value just past a bound would read as the bound, or as a
            // value inside: then it is shown with every digit.
            let mut shown = short_number(v);
            if shown == short_number(self.lo)
                || shown == short_number(self.hi)
                || shown.parse::<f64>().is_ok_and(|s| self.contains(s))
            {
                shown = format!("{v}");
            }
            Err(Error::Parameter(format!("{who}: {name} must be in {self}{unit}, got {shown}")))
        }
    }
}

impl fmt::Display for Interval {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let open = if self.lo_closed { '[' } else { '(' };
        let close = if self.hi_closed { ']' } else { ')' };
        write!(f, "{open}{}, {}{close}", short_number(self.lo), short_number(self.hi))
    }
}

/// `Ok` when `lo ≤ v ≤ hi`; otherwise an [`Error::Parameter`]
/// `"{who}: {name} must be in {lo} ..= {hi}, got {v}"`.
pub fn check_count(who: &str, name: &str, v: usize, lo: usize, hi: usize) -> Result<()> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(Error::Parameter(format!("{who}: {name} must be in {lo} ..= {hi}, got {v}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_numbers_stay_short() {
        assert_eq!(short_number(12.5), "12.5");
        assert_eq!(short_number(0.0), "0");
        assert_eq!(short_number(-3.0), "-3");
        assert_eq!(short_number(1e300), "1.0e300");
        assert_eq!(short_number(-2.5e-12), "-2.5e-12");
        assert_eq!(short_number(123_456_789_012.0), "1.235e11");
        assert_eq!(short_number(f64::NAN), "NaN");
        assert_eq!(short_number(f64::INFINITY), "inf");
        assert_eq!(short_number(std::f64::consts::FRAC_PI_2), "1.5708");
    }

    #[test]
    fn long_digit_runs_are_shortened() {
        let huge = format!("1{}", "0".repeat(300));
        assert_eq!(shorten_digit_runs(&format!("x = {huge} overflowed")), "x = 1.0e300 overflowed");
        assert_eq!(shorten_digit_runs(&format!("`{huge}.0`")), "`1.0e300`");
        assert_eq!(shorten_digit_runs("line 2, column 21: 1e9 ≤ 12"), "line 2, column 21: 1e9 ≤ 12");
    }

    #[test]
    fn intervals_check_both_ends_and_refuse_nan() {
        let i = Interval::open_closed(0.0, 1000.0);
        assert!(i.contains(1000.0) && !i.contains(0.0) && !i.contains(f64::NAN) && !i.contains(1e30));
        let msg = i.check("blue", "acquire_distance", 1e300, " px").unwrap_err().to_string();
        assert_eq!(msg, "invalid parameter: blue: acquire_distance must be in (0, 1000] px, got 1.0e300");
        assert!(Interval::closed(0.0, f64::INFINITY).contains(f64::INFINITY));
        assert!(!Interval::open(0.0, 1.0).contains(1.0));
        assert!(check_count("m", "n", 7, 0, 6).unwrap_err().to_string().contains("0 ..= 6, got 7"));
        // Just past a bound, the value is not shown as the bound itself.
        let msg = Interval::closed(0.5, 4.0).check("lowe", "log_sigma", f64::from(4.000_000_5_f32), "").unwrap_err();
        assert!(msg.to_string().ends_with("must be in [0.5, 4], got 4.000000476837158"), "{msg}");
        let past_pi = f64::from_bits(std::f64::consts::PI.to_bits() + 1);
        let msg = Interval::open_closed(0.0, std::f64::consts::PI).check("t", "a", past_pi, " rad").unwrap_err();
        assert!(msg.to_string().ends_with("must be in (0, 3.1416] rad, got 3.1415926535897936"), "{msg}");
    }
}
