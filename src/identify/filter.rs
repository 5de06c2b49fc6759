//! Zero-phase low-pass filtering and differentiation of sampled signals.
//!
//! The filter is a fourth-order Butterworth low-pass (two second-order sections from the bilinear
//! transform, the cut-off prewarped) run forwards and then backwards over the signal: the phase
//! shifts cancel, so a filtered signal is not delayed against another, and the magnitude response
//! is squared (1/2 at the cut-off, 1 − (f/f_c)⁸ well below it). Before filtering the signal is
//! extended at each end over the filter's settling length [`LowPass::settle`] (each pass starts
//! from the steady state of its first value, a transient that has died out by the time it
//! reaches the signal): by its point reflection 2 x₀ − x₋ₖ ([`Extension::Odd`], which keeps value
//! and slope at the end, so a run's ends are not pulled towards zero) or its mirror image x₋ₖ
//! ([`Extension::Even`]). An equation ẋ + y = 0 that holds on a run still holds on the even
//! extensions of ẋ and y, and so on the filtered signals right up to the run's ends: the
//! derivative is taken before the extension (a derivative taken after it is one-sided at the
//! ends).
//!
//! Derivatives are fourth-order central differences of smoothed signals ([`central`]): for a
//! signal band-limited well below the sampling rate their error is (ω Δt)⁴/30 of the derivative
//! (the second-order (x₊₁ − x₋₁) / 2Δt leaves (ω Δt)²/6, which for a swing's harmonics at a
//! kilohertz is already 10⁻⁵ of the velocity, a bias the rates would inherit).

/// What may remain of a filter's impulse response past the samples a run's ends are dropped
/// for: with 10⁻⁴, a run's ends move an estimate by far less than the encoder noise does.
pub const SETTLED: f64 = 1e-4;

/// How a signal is continued beyond its ends before it is filtered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extension {
    /// Point reflection, 2 x₀ − x₋ₖ: value and slope continue.
    Odd,
    /// Mirror image, x₋ₖ: the value continues, the slope flips.
    Even,
}

/// A zero-phase fourth-order Butterworth low-pass at one sampling rate.
#[derive(Debug, Clone, PartialEq)]
pub struct LowPass {
    /// The two sections: b₀, b₁, b₂, a₁, a₂ (a₀ = 1), direct form II transposed.
    sections: [[f64; 5]; 2],
    /// Samples after which what is left of the impulse response of one pass is at most
    /// [`SETTLED`] of its whole (in absolute sum).
    settle: usize,
    /// The cut-off, Hz.
    pub cutoff_hz: f64,
    /// The sampling rate, Hz.
    pub rate_hz: f64,
}

impl LowPass {
    /// The filter with cut-off `cutoff_hz` for samples at `rate_hz` (the cut-off below the Nyquist
    /// frequency rate/2; the caller checks).
    pub fn butterworth(cutoff_hz: f64, rate_hz: f64) -> LowPass {
        let k = 2.0 * rate_hz;
        // The analogue cut-off that the bilinear transform maps onto cutoff_hz.
        let w = k * (std::f64::consts::PI * cutoff_hz / rate_hz).tan();
        let section = |theta: f64| {
            let a1 = 2.0 * theta.sin() * w;
            let a0 = k * k + a1 * k + w * w;
            let b = w * w / a0;
            [b, 2.0 * b, b, (2.0 * w * w - 2.0 * k * k) / a0, (k * k - a1 * k + w * w) / a0]
        };
        // Poles of the fourth-order prototype at angles π/8 and 3π/8 from the imaginary axis.
        let pi = std::f64::consts::PI;
        let mut f = LowPass { sections: [section(pi / 8.0), section(3.0 * pi / 8.0)], settle: 0, cutoff_hz, rate_hz };
        f.settle = f.settling_length();
        f
    }

    /// Samples at each end of a filtered signal that still depend on how it was extended.
    pub fn settle(&self) -> usize {
        self.settle
    }

    fn settling_length(&self) -> usize {
        // The impulse response decays like exp(−2π f_c sin(π/8) t); look well beyond that.
        let cap = (60.0 * self.rate_hz / self.cutoff_hz).ceil() as usize + 16;
        let mut x = vec![0.0; cap];
        x[0] = 1.0;
        let h = self.pass(&x, 0.0);
        let total: f64 = h.iter().map(|v| v.abs()).sum();
        let mut tail = total;
        for (i, v) in h.iter().enumerate() {
            if tail <= SETTLED * total {
                return i.max(1);
            }
            tail -= v.abs();
        }
        cap
    }

    /// One forward pass over `x`, every section started at the steady state of input `x0`.
    ///
    /// Both sections run in one sweep, each sample through the first and then the second: the
    /// same operations as one sweep per section, so the same values, but the two recurrences
    /// overlap in the processor instead of waiting on each other (the filters were half the
    /// cost of the plan's regression rows on three joints).
    fn pass(&self, x: &[f64], x0: f64) -> Vec<f64> {
        let mut y = x.to_vec();
        // Steady state: constant input x0, constant output x0 (unit gain at DC, so the next
        // section sees x0 too). State (z1, z2) per section.
        let mut z = self.sections.map(|[_, b1, b2, a1, a2]| {
            let z2 = (b2 - a2) * x0;
            ((b1 - a1) * x0 + z2, z2)
        });
        for v in y.iter_mut() {
            let mut input = *v;
            for ([b0, b1, b2, a1, a2], (z1, z2)) in self.sections.iter().zip(z.iter_mut()) {
                let out = b0 * input + *z1;
                *z1 = b1 * input - a1 * out + *z2;
                *z2 = b2 * input - a2 * out;
                input = out;
            }
            *v = input;
        }
        y
    }

    /// The signal filtered forwards and backwards (zero phase), extended odd at its ends.
    pub fn filtfilt(&self, x: &[f64]) -> Vec<f64> {
        self.filtfilt_extended(x, Extension::Odd)
    }

    /// The signal filtered forwards and backwards (zero phase), extended as `extension` says
    /// (over at most its length less one sample: a run shorter than [`LowPass::settle`] keeps
    /// some of the start transient).
    pub fn filtfilt_extended(&self, x: &[f64], extension: Extension) -> Vec<f64> {
        let n = x.len();
        if n == 0 {
            return Vec::new();
        }
        // A signal of zeros (a part's column on a joint its coupling leaves out: 158 of the 423
        // columns of a bill of 141 parts on three joints) extends to zeros either way and passes
        // as zeros: no sweep needed.
        if x.iter().all(|v| *v == 0.0) {
            return vec![0.0; n];
        }
        let pad = self.settle.min(n - 1);
        let (a, b) = match extension {
            Extension::Odd => (2.0 * x[0], 2.0 * x[n - 1]),
            Extension::Even => (0.0, 0.0),
        };
        let sign = if extension == Extension::Odd { -1.0 } else { 1.0 };
        let mut ext = Vec::with_capacity(n + 2 * pad);
        ext.extend((1..=pad).rev().map(|k| a + sign * x[k]));
        ext.extend_from_slice(x);
        ext.extend((1..=pad).map(|k| b + sign * x[n - 1 - k]));
        let forward = self.pass(&ext, ext[0]);
        let mut reversed: Vec<f64> = forward.into_iter().rev().collect();
        let first = reversed[0];
        reversed = self.pass(&reversed, first);
        reversed.reverse();
        reversed.drain(..pad);
        reversed.truncate(n);
        reversed
    }
}

/// The time derivative of evenly sampled `x` (interval `dt`): fourth-order central differences
/// ([`central`]) inside, second-order ones one sample in, one-sided differences at the two ends.
pub fn derivative(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    if n < 2 {
        return vec![0.0; n];
    }
    (0..n)
        .map(|i| match i {
            0 => (x[1] - x[0]) / dt,
            _ if i == n - 1 => (x[n - 1] - x[n - 2]) / dt,
            _ if i == 1 || i == n - 2 => (x[i + 1] - x[i - 1]) / (2.0 * dt),
            _ => central(&x[i - 2..=i + 2], dt),
        })
        .collect()
}

/// The derivative at the middle of five samples `dt` apart, (x₋₂ − 8 x₋₁ + 8 x₊₁ − x₊₂) / 12Δt:
/// for a signal band-limited well below the sampling rate its error is (ω Δt)⁴/30 of the
/// derivative.
pub fn central(x: &[f64], dt: f64) -> f64 {
    (x[0] - 8.0 * x[1] + 8.0 * x[3] - x[4]) / (12.0 * dt)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::rng::SplitMix64;
    use std::f64::consts::TAU;

    fn sine(f: f64, rate: f64, seconds: f64) -> Vec<f64> {
        (0..(seconds * rate) as usize).map(|i| (TAU * f * i as f64 / rate).sin()).collect()
    }

    /// Largest |x| away from the ends.
    fn inner_max(x: &[f64], skip: usize) -> f64 {
        x[skip..x.len() - skip].iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }

    #[test]
    fn the_response_is_squared_butterworth_without_delay() {
        let (fc, rate) = (4.0, 1000.0);
        let f = LowPass::butterworth(fc, rate);
        let skip = f.settle();
        // |H|² = 1 / (1 + (f/fc)⁸) forwards and backwards: 1/2 at the cut-off.
        for (freq, want) in [(fc, 0.5), (2.0 * fc, 1.0 / 257.0), (fc / 4.0, 1.0 / (1.0 + 0.25f64.powi(8)))] {
            let y = f.filtfilt(&sine(freq, rate, 12.0));
            let gain = inner_max(&y, skip);
            assert!((gain - want).abs() < 2e-4 * want.max(0.01) + 1e-4, "{freq} Hz: gain {gain}, want {want}");
        }
        // No delay: the filtered slow sine lies on the input scaled by its gain.
        let x = sine(0.5, rate, 12.0);
        let y = f.filtfilt(&x);
        let err = x.iter().zip(&y).skip(skip).take(x.len() - 2 * skip).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(err < 1e-6, "zero phase: {err}");
        // A constant passes unchanged up to the very ends.
        let c = f.filtfilt(&[2.5; 400]);
        assert!(c.iter().all(|v| (v - 2.5).abs() < 1e-12), "{:?}", &c[..3]);
    }

    #[test]
    fn the_derivative_of_a_filtered_signal_is_the_filtered_derivative() {
        // q = sin(ωt) + 0.2 sin(3ωt): the velocity from the smoothed angles, and the derivative
        // of a low-passed momentum-like signal against the low-passed exact acceleration.
        let (rate, w) = (1000.0, 4.0);
        let n = 12_000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / rate).collect();
        let q: Vec<f64> = t.iter().map(|t| (w * t).sin() + 0.2 * (3.0 * w * t).sin()).collect();
        let qd: Vec<f64> = t.iter().map(|t| w * (w * t).cos() + 0.6 * w * (3.0 * w * t).cos()).collect();
        let qdd: Vec<f64> = t.iter().map(|t| -w * w * (w * t).sin() - 1.8 * w * w * (3.0 * w * t).sin()).collect();
        let smooth = LowPass::butterworth(50.0, rate);
        let v = derivative(&smooth.filtfilt(&q), 1.0 / rate);
        let s = smooth.settle() + 1;
        let err = (s..n - s).map(|i| (v[i] - qd[i]).abs()).fold(0.0, f64::max);
        assert!(err < 2e-5 * 6.4, "velocity error {err}");
        let low = LowPass::butterworth(3.8, rate);
        let a = derivative(&low.filtfilt(&qd), 1.0 / rate);
        let want = low.filtfilt(&qdd);
        let s = low.settle() + 1;
        let err = (s..n - s).map(|i| (a[i] - want[i]).abs()).fold(0.0, f64::max);
        // The central difference's own error, (ω Δt)²/6 of the 3ω component's 29 rad/s².
        let bound = (12.0f64 * 1e-3).powi(2) / 6.0 * 29.0;
        assert!(err < 1.2 * bound, "d/dt L[q̇] − L[q̈]: {err} (central differences: {bound})");
    }

    #[test]
    fn an_equation_holds_on_the_filtered_signals_up_to_the_ends() {
        // ẋ + y = 0 on a run that starts and ends mid-swing. Differenced first (x known one
        // sample beyond each end), then both terms extended even and filtered: L[Dx] + L[y]
        // stays at the central difference's error (ω Δt)²/6 of ẋ everywhere. Filtered after an
        // odd extension and then differenced, the two ends carry a one-sided difference instead.
        let (rate, w, len) = (1000.0, 5.0, 4000);
        let at = |i: usize| w * (i as f64 - 1.0) / rate + 0.7;
        let x: Vec<f64> = (0..len + 2).map(|i| at(i).sin()).collect();
        let y: Vec<f64> = (1..=len).map(|i| -w * at(i).cos()).collect();
        let dx: Vec<f64> = (0..len).map(|i| (x[i + 2] - x[i]) * rate / 2.0).collect();
        let f = LowPass::butterworth(3.8, rate);
        let ly = f.filtfilt_extended(&y, Extension::Even);
        let ldx = f.filtfilt_extended(&dx, Extension::Even);
        let consistent = (0..len).map(|i| (ldx[i] + ly[i]).abs()).fold(0.0, f64::max);
        let bound = (w / rate).powi(2) / 6.0 * w;
        assert!(consistent < 1.05 * bound, "{consistent} against the central difference's {bound}");
        let dlx = derivative(&f.filtfilt(&x[1..=len]), 1.0 / rate);
        let after = (1..len - 1).map(|i| (dlx[i] + ly[i]).abs()).fold(0.0, f64::max);
        assert!(after > 5.0 * bound, "differencing after the extension: {after}");
    }

    #[test]
    fn quantised_noisy_angles_give_the_predicted_velocity_noise() {
        // A 17-bit encoder (2π/2¹⁷ per count) with one count of rms noise before quantisation:
        // the velocity error of smoothing + central differences is σ √(Σ hₖ²), h the impulse
        // response of the two operations, σ² = (1 + 1/12) counts² (noise plus quantisation).
        let (rate, count) = (1000.0, TAU / 131_072.0);
        let smooth = LowPass::butterworth(50.0, rate);
        let n = 20_000;
        let mut rng = SplitMix64::stream(7, 0);
        let exact: Vec<f64> = (0..n).map(|i| 0.8 * (2.5 * i as f64 / rate).sin()).collect();
        let read: Vec<f64> = exact.iter().map(|q| ((q + count * rng.normal()) / count).round() * count).collect();
        let v = derivative(&smooth.filtfilt(&read), 1.0 / rate);
        let v0 = derivative(&smooth.filtfilt(&exact), 1.0 / rate);
        let s = smooth.settle() + 1;
        let rms = ((s..n - s).map(|i| (v[i] - v0[i]).powi(2)).sum::<f64>() / (n - 2 * s) as f64).sqrt();
        let mut impulse = vec![0.0; 2001];
        impulse[1000] = 1.0;
        let h = derivative(&smooth.filtfilt(&impulse), 1.0 / rate);
        let gain = h.iter().map(|x| x * x).sum::<f64>().sqrt();
        let predicted = count * (1.0 + 1.0 / 12.0f64).sqrt() * gain;
        assert!((rms / predicted - 1.0).abs() < 0.1, "velocity noise {rms:.3e}, predicted {predicted:.3e}");
        // Smoothing keeps it far below the raw differences' noise.
        let raw = derivative(&read, 1.0 / rate);
        let raw_rms = ((s..n - s).map(|i| (raw[i] - v0[i]).powi(2)).sum::<f64>() / (n - 2 * s) as f64).sqrt();
        assert!(rms < raw_rms / 10.0, "{rms} vs raw {raw_rms}");
    }
}
