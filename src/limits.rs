//! Every limit springfit puts on its input, in one place (and in `docs/limits.md`, which a test
//! keeps in step with this file).
//!
//! Two kinds of limit. **Physical magnitudes** (angles, masses, lengths, rates) are bounded far
//! beyond any arm a workshop builds but well inside what 64-bit floats compute with: a link of
//! 1e200 kg next to one of 1 kg makes a mass matrix no factorisation can tell from singular, and
//! an angle of 1e300 rad has no digits left below a full turn. A value beyond its bound is refused
//! with the bound in the message rather than failing later in a solver. **Counts** (threads,
//! builds, samples, knots) are bounded by what the machine can do: a count far beyond it would
//! not fail, it would run for hours or exhaust the memory.

/// Most joints of a chain (planar links, or the moving joints of a URDF).
pub(crate) const MAX_LINKS: usize = 8;

/// Largest |angle| in rad anywhere (equilibrium, region bounds, offsets, starts, held joints):
/// about 159 turns. Joint angles are unwrapped, but no arm turns that far.
pub(crate) const MAX_ANGLE_RAD: f64 = 1e3;

/// Largest link mass, kg.
pub(crate) const MAX_MASS_KG: f64 = 1e6;

/// Largest link length, |centre of mass| or |joint origin| offset, m.
pub(crate) const MAX_LENGTH_M: f64 = 1e3;

/// Largest moment of inertia (any entry of an inertia tensor), kg·m².
pub(crate) const MAX_INERTIA_KGM2: f64 = 1e9;

/// Largest |gravity|, m/s² (a hundred times the Earth's).
pub(crate) const MAX_GRAVITY: f64 = 1e3;

/// Largest |entry| of a coupling vector a (a gear ratio).
pub(crate) const MAX_COUPLING: f64 = 1e3;

/// Largest stiffness, in any element's unit (N·m/rad, N·m/rad³, N·m, J, N/mm), and largest
/// stock rate, trim rate or `max_stiffness`.
pub(crate) const MAX_STIFFNESS: f64 = 1e9;

/// Largest small-oscillation frequency ω, rad/s.
pub(crate) const MAX_FREQUENCY: f64 = 1e4;

/// Worker threads per core the machine reports (`--threads` above this many times the
/// available parallelism is refused).
pub const MAX_THREADS_PER_CORE: usize = 4;

/// Most offsets of one family per coupling (`{ grid = N }`, `{ phases = N }`).
pub(crate) const MAX_OFFSETS: usize = 1000;

/// Most trim springs one design may carry (the trim solve enumerates 3^m faces).
pub(crate) const MAX_TRIMS: usize = 9;

/// Most candidate elements a catalogue may expand into (the shipped catalogues have about 500).
pub(crate) const MAX_CANDIDATES: usize = 20_000;

/// Most knots of a cam.
pub(crate) const MAX_KNOTS: usize = 500;

/// Memory the fit's least-squares problem (its dense rows, or the rows' factors where the normal
/// equations come from them) may take when the machine does not say how much it has, bytes
/// (8 GiB). On Linux the limit is the memory the system reports available.
pub(crate) const DEFAULT_FIT_MEMORY: u64 = 8 << 30;

/// The memory the system reports available (Linux: `MemAvailable` of `/proc/meminfo`), else
/// [`DEFAULT_FIT_MEMORY`]: what the fit's problem may take.
pub(crate) fn available_memory() -> u64 {
    let kib = std::fs::read_to_string("/proc/meminfo").ok().and_then(|text| {
        text.lines()
            .find_map(|l| l.strip_prefix("MemAvailable:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
    });
    kib.map_or(DEFAULT_FIT_MEMORY, |k| k.saturating_mul(1024))
}

/// Checks that `x` is finite and |x| ≤ `max`; the error says so in words with the unit.
pub(crate) fn within(x: f64, max: f64, unit: &str) -> Result<(), String> {
    if !x.is_finite() {
        return Err(format!("must be a finite number, got {x}"));
    }
    if x.abs() > max {
        return Err(format!("{} is beyond the largest springfit accepts, {}{unit} in magnitude", show(x), show(max)));
    }
    Ok(())
}

/// A number as a message shows it: Rust's shortest round-trip text, in scientific notation when
/// it would be long (|x| ≥ 1e6 or below 1e-5): `1e300`, not three hundred digits.
pub(crate) fn show(x: f64) -> String {
    if x.is_finite() && x != 0.0 && (x.abs() >= 1e6 || x.abs() < 1e-5) { format!("{x:e}") } else { format!("{x}") }
}

/// `text` with every number written out in more than 16 digits (Rust prints 1e300 as three
/// hundred of them) replaced by its scientific notation: what every error message goes through.
pub(crate) fn tidy_numbers(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit() && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'.'));
        if starts {
            let mut j = i;
            while j < b.len() && b[j].is_ascii_digit() {
                j += 1;
            }
            if j < b.len() && b[j] == b'.' && j + 1 < b.len() && b[j + 1].is_ascii_digit() {
                j += 1;
                while j < b.len() && b[j].is_ascii_digit() {
                    j += 1;
                }
            }
            let token = &text[i..j];
            let digits = token.bytes().filter(u8::is_ascii_digit).count();
            match token.parse::<f64>() {
                Ok(v) if digits > 16 && v.is_finite() => out.push_str(&show(v)),
                _ => out.push_str(token),
            }
            i = j;
        } else {
            let len = text[i..].chars().next().map_or(1, char::len_utf8);
            out.push_str(&text[i..i + len]);
            i += len;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_numbers_are_shortened_and_others_kept() {
        let huge = format!("got {}", 1e300);
        assert!(huge.len() > 300);
        assert_eq!(tidy_numbers(&huge), "got 1e300");
        let tiny = format!("spacing {} rad", 1.5e-30);
        assert_eq!(tidy_numbers(&tiny), "spacing 1.5e-30 rad");
        let plain = "line 12: stiffness 31.25 N·m/rad, S01, 1e300 already short, 0.1234567890123";
        assert_eq!(tidy_numbers(plain), plain);
        assert_eq!(show(2.0), "2");
        assert_eq!((show(1e8), show(123456.0)), ("1e8".to_string(), "123456".to_string()));
        assert_eq!(
            within(1e200, MAX_MASS_KG, " kg").unwrap_err(),
            "1e200 is beyond the largest springfit accepts, 1e6 kg in magnitude"
        );
        assert!(within(f64::NAN, 1.0, "").unwrap_err().contains("finite"));
        assert!(within(-3.0, 5.0, " m").is_ok());
    }
}
