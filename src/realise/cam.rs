//! Realising a fitted cam profile as hardware: a disc cam geared to its coupling, turned
//! [`CAM_TURN_DEG`] over the knot span, with a roller follower on a preloaded linear spring. The
//! follower spring stores V − min V, which fixes the stroke s(x); the pitch curve, the pressure
//! angle and the radius of curvature follow, and the limits a cam maker checks (pressure angle,
//! undercut) are reported. `svg` draws the cam profile to scale.

use crate::elements::spline::Knots;

/// Cam angle the coupling's range is geared to: 300°, so the cam never turns a full turn.
pub const CAM_TURN_DEG: f64 = 300.0;

/// Follower preload at the base circle as a fraction of the largest stroke. Without preload
/// s(x) = sqrt(2 (V − min V)/k_f) has a corner at the minimum of V (infinite curvature).
pub const PRELOAD_FRACTION: f64 = 0.5;

/// Smallest allowed margin between the pitch curve's radius of curvature (where convex) and the
/// roller radius, in mm: below it the cam profile undercuts.
pub const MIN_CURVATURE_MARGIN_MM: f64 = 1.0;

/// How a cam is built: a disc cam geared to the coupling, a roller follower on a linear spring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamBuild {
    /// Follower spring rate k_f in N/mm.
    pub follower_rate: f64,
    /// Follower preload p₀ at the base circle in mm.
    pub preload: f64,
    /// Gear ratio g: the cam turns by φ = (x − x_lo)/g.
    pub gear_ratio: f64,
    /// Base-circle radius R_b in mm.
    pub base_radius: f64,
    /// Roller radius ρ_r in mm.
    pub roller_radius: f64,
}

/// One point of a realised cam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamPoint {
    /// Coupling coordinate x in rad.
    pub x: f64,
    /// V(x) − min V in J.
    pub potential: f64,
    /// V′(x) in N·m (torque on x).
    pub torque: f64,
    /// Follower stroke s in mm.
    pub stroke: f64,
    /// Pitch radius R = R_b + ρ_r + s in mm.
    pub pitch_radius: f64,
    /// Pressure angle in degrees.
    pub pressure_angle: f64,
    /// Radius of curvature of the pitch curve in mm, negative where it is concave.
    pub curvature_radius: f64,
}

/// A realised cam: its build and its profile sampled evenly over the knot span.
#[derive(Debug, Clone, PartialEq)]
pub struct Realisation {
    /// The build.
    pub build: CamBuild,
    /// The samples (≥ 1000).
    pub points: Vec<CamPoint>,
    /// Largest |pressure angle| in degrees.
    pub max_pressure_angle: f64,
    /// Smallest radius of curvature of the pitch curve where it is convex, mm.
    pub min_convex_curvature: f64,
    /// Limits the cam violates, in words with their numbers (empty: within limits).
    pub violations: Vec<String>,
}

/// Realises V(x) = Σ cⱼ Bⱼ(x) over the knot span as a disc cam with a roller follower.
///
/// The follower spring stores V − min V = ½ k_f ((p₀ + s)² − p₀²), so
/// s = sqrt(p₀² + 2 (V − min V)/k_f) − p₀ (k_f in N/m, lengths in m inside). Given no rate, k_f
/// is chosen so the largest stroke is `max_stroke` with p₀ = [`PRELOAD_FRACTION`] · `max_stroke`;
/// given a rate, p₀ is that fraction of the stroke the rate gives. The cam turns
/// [`CAM_TURN_DEG`] over the span: g = (x_hi − x_lo)/300°. With φ the cam angle,
/// R(φ) = R_b + ρ_r + s, the pressure angle is atan(R′/R) and the pitch curve's radius of
/// curvature (R² + R′²)^{3/2} / (R² + 2R′² − R R″).
#[allow(clippy::too_many_arguments)]
pub fn realise(
    knots: &Knots,
    c: &[f64],
    follower_rate: Option<f64>,
    max_stroke: f64,
    base_radius: f64,
    roller_radius: f64,
    max_pressure_angle: f64,
    samples: usize,
) -> Realisation {
    let profile = |x: f64| knots.eval(c, x);
    let (span, angle) = ([knots.lo, knots.hi()], max_pressure_angle);
    realise_profile(span, profile, follower_rate, max_stroke, base_radius, roller_radius, angle, samples)
}

/// Realises any potential `profile(x) = (V, V′, V″)` over `span` as [`realise`] does a fitted
/// B-spline: what a hardening (cubic) element is built as, since no wound spring's torque grows
/// as the cube of its deflection.
#[allow(clippy::too_many_arguments)]
pub fn realise_profile(
    span: [f64; 2],
    profile: impl Fn(f64) -> (f64, f64, f64),
    follower_rate: Option<f64>,
    max_stroke: f64,
    base_radius: f64,
    roller_radius: f64,
    max_pressure_angle: f64,
    samples: usize,
) -> Realisation {
    let samples = samples.max(1000);
    let [lo, hi] = span;
    let xs: Vec<f64> = (0..samples).map(|i| lo + (hi - lo) * i as f64 / (samples - 1) as f64).collect();
    let vals: Vec<(f64, f64, f64)> = xs.iter().map(|&x| profile(x)).collect();
    let v_min = vals.iter().map(|v| v.0).fold(f64::INFINITY, f64::min);
    let dv_max = vals.iter().map(|v| v.0 - v_min).fold(0.0, f64::max);
    // Rate in N/m and preload in m.
    let (k, p0) = match follower_rate {
        Some(rate) => {
            let k = rate * 1000.0;
            // Stroke S with p₀ = f S: ΔV = ½ k S² (1 + 2f).
            let stroke = (2.0 * dv_max / (k * (1.0 + 2.0 * PRELOAD_FRACTION))).sqrt();
            (k, PRELOAD_FRACTION * stroke.max(1e-6))
        }
        None => {
            let stroke = max_stroke / 1000.0;
            let p0 = PRELOAD_FRACTION * stroke;
            ((2.0 * dv_max / ((p0 + stroke).powi(2) - p0 * p0)).max(1e-9), p0)
        }
    };
    let g = (hi - lo) / CAM_TURN_DEG.to_radians();
    let build = CamBuild { follower_rate: k / 1000.0, preload: p0 * 1000.0, gear_ratio: g, base_radius, roller_radius };
    let mut points = Vec::with_capacity(samples);
    for (&x, &(v, dv, ddv)) in xs.iter().zip(&vals) {
        let e = v - v_min;
        let s = stroke(e, k, p0);
        // s′ = V′/(k (p₀ + s)), s″ = (V″ − k s′²)/(k (p₀ + s)) in x; ×g, ×g² per cam angle; mm.
        let ds = dv / (k * (p0 + s));
        let dds = (ddv - k * ds * ds) / (k * (p0 + s));
        let r = base_radius + roller_radius + 1000.0 * s;
        let r1 = 1000.0 * g * ds;
        let r2 = 1000.0 * g * g * dds;
        let denom = r * r + 2.0 * r1 * r1 - r * r2;
        let rho = (r * r + r1 * r1).powf(1.5) / denom;
        points.push(CamPoint {
            x,
            potential: e,
            torque: dv,
            stroke: 1000.0 * s,
            pitch_radius: r,
            pressure_angle: (r1 / r).atan().to_degrees(),
            curvature_radius: rho,
        });
    }
    let max_alpha = points.iter().map(|p| p.pressure_angle.abs()).fold(0.0, f64::max);
    let min_rho =
        points.iter().filter(|p| p.curvature_radius > 0.0).map(|p| p.curvature_radius).fold(f64::INFINITY, f64::min);
    let mut violations = Vec::new();
    if max_alpha > max_pressure_angle {
        violations.push(format!("pressure angle reaches {max_alpha:.1}° (limit {max_pressure_angle}°)"));
    }
    if min_rho < roller_radius + MIN_CURVATURE_MARGIN_MM {
        violations.push(format!(
            "the pitch curve's smallest convex radius of curvature is {min_rho:.2} mm, below the roller radius \
             {roller_radius} mm + {MIN_CURVATURE_MARGIN_MM} mm: the profile undercuts"
        ));
    }
    Realisation { build, points, max_pressure_angle: max_alpha, min_convex_curvature: min_rho, violations }
}

/// s = sqrt(p₀² + 2 E/k) − p₀, written to keep its relative accuracy when 2E/k ≪ p₀².
pub fn stroke(energy: f64, k: f64, p0: f64) -> f64 {
    let q = 2.0 * energy.max(0.0) / k;
    q / ((p0 * p0 + q).sqrt() + p0)
}

/// The cam outline (inner envelope of the roller over the pitch curve) at 1:1 in mm as SVG, with
/// the cam's centre, the base circle and a zero mark (x = x_lo, cam angle 0).
pub fn svg(r: &Realisation, title: &str) -> String {
    let g = r.build.gear_ratio;
    let lo = r.points[0].x;
    // Pitch curve in the cam's frame: the cam turns by +φ, so the follower sits at angle −φ.
    let pitch: Vec<(f64, f64)> = r
        .points
        .iter()
        .map(|p| {
            let phi = -(p.x - lo) / g;
            (p.pitch_radius * phi.cos(), p.pitch_radius * phi.sin())
        })
        .collect();
    let n = pitch.len();
    let mut profile = Vec::with_capacity(n);
    for i in 0..n {
        let (a, b) = (pitch[i.saturating_sub(1)], pitch[(i + 1).min(n - 1)]);
        let (tx, ty) = (b.0 - a.0, b.1 - a.1);
        let len = tx.hypot(ty).max(1e-300);
        // The pitch curve runs clockwise (φ grows, angle −φ falls): its outward normal is (−ty, tx)/len.
        let (nx, ny) = (-ty / len, tx / len);
        profile.push((pitch[i].0 - r.build.roller_radius * nx, pitch[i].1 - r.build.roller_radius * ny));
    }
    let extent = r.points.iter().map(|p| p.pitch_radius).fold(0.0, f64::max) + 5.0;
    let size = 2.0 * extent;
    let mut path = String::new();
    for (i, (x, y)) in profile.iter().enumerate() {
        path.push_str(&format!("{}{:.4},{:.4} ", if i == 0 { "M" } else { "L" }, x, -y));
    }
    path.push('Z');
    let rb = r.build.base_radius;
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{size:.3}mm\" height=\"{size:.3}mm\" viewBox=\"{:.3} {:.3} {size:.3} {size:.3}\">\n\
         <title>{}</title>\n\
         <path d=\"{path}\" fill=\"none\" stroke=\"black\" stroke-width=\"0.2\"/>\n\
         <circle cx=\"0\" cy=\"0\" r=\"{rb}\" fill=\"none\" stroke=\"grey\" stroke-width=\"0.1\" stroke-dasharray=\"1,1\"/>\n\
         <path d=\"M-3,0 L3,0 M0,-3 L0,3\" stroke=\"black\" stroke-width=\"0.2\"/>\n\
         <path d=\"M{:.3},0 L{:.3},0\" stroke=\"red\" stroke-width=\"0.4\"/>\n\
         </svg>\n",
        -extent,
        -extent,
        title.replace('&', "&amp;").replace('<', "&lt;"),
        rb - 4.0,
        extent,
    )
}

/// A fitted cam: its coupling, knots, coefficients and realisation.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedCam {
    /// `C01`, `C02`, … (the prefix of its basis rows in the bill of materials).
    pub id: String,
    /// Catalogue family name.
    pub family: String,
    /// Coupling a.
    pub coupling: Vec<f64>,
    /// Knots.
    pub knots: Knots,
    /// Coefficients cⱼ in J (c = k⁺ − k⁻).
    pub coefficients: Vec<f64>,
    /// The disc cam that realises it.
    pub realisation: Realisation,
}

/// Follower rate, largest stroke (mm), base and roller radius (mm) and pressure-angle limit (°)
/// of a cam whose family is unknown: the catalogue's defaults.
pub const DEFAULT_REALISATION: (Option<f64>, f64, f64, f64, f64) = (None, 20.0, 40.0, 8.0, 30.0);

/// A cam realised with [`DEFAULT_REALISATION`].
pub fn realise_default(knots: &Knots, c: &[f64]) -> Realisation {
    let (rate, stroke, rb, rr, alpha) = DEFAULT_REALISATION;
    realise(knots, c, rate, stroke, rb, rr, alpha, 1000)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn knots() -> Knots {
        Knots::over(-1.3, 2.1, 12, 0.05)
    }

    #[test]
    fn follower_stroke_stores_the_potential() {
        let k = knots();
        let c: Vec<f64> = (0..k.basis_count()).map(|j| 3.0 * (j as f64 * 0.7).sin() + 0.2 * j as f64).collect();
        let r = realise(&k, &c, None, 20.0, 40.0, 8.0, 30.0, 1000);
        assert_eq!(r.points.len(), 1000);
        let (kf, p0) = (r.build.follower_rate * 1000.0, r.build.preload / 1000.0);
        let max_s = r.points.iter().map(|p| p.stroke).fold(0.0, f64::max);
        assert!((max_s - 20.0).abs() < 1e-9, "{max_s}");
        for p in &r.points {
            // ½ k ((p₀ + s)² − p₀²) = V − min V.
            let s = p.stroke / 1000.0;
            let stored = 0.5 * kf * ((p0 + s).powi(2) - p0 * p0);
            assert!((stored - p.potential).abs() <= 1e-9 * p.potential.max(1e-12), "{stored} vs {}", p.potential);
        }
        // A given rate: the same identity, another stroke.
        let r2 = realise(&k, &c, Some(2.0), 20.0, 40.0, 8.0, 30.0, 1000);
        assert_eq!(r2.build.follower_rate, 2.0);
        let p0 = r2.build.preload / 1000.0;
        for p in &r2.points {
            let s = p.stroke / 1000.0;
            let stored = 0.5 * 2000.0 * ((p0 + s).powi(2) - p0 * p0);
            assert!((stored - p.potential).abs() <= 1e-9 * p.potential.max(1e-12));
        }
        // The cam turns 300° over the span.
        assert!(((k.hi() - k.lo) / r.build.gear_ratio - 300f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn too_steep_a_profile_is_flagged() {
        let k = knots();
        let gentle: Vec<f64> = (0..k.basis_count()).map(|j| 0.05 * (j as f64 - 6.0).powi(2)).collect();
        let r = realise(&k, &gentle, None, 10.0, 60.0, 5.0, 30.0, 1000);
        assert!(r.violations.is_empty(), "{:?}", r.violations);
        assert!(r.max_pressure_angle > 0.0 && r.max_pressure_angle < 30.0);
        // A jump in V over one knot on a small base circle: the follower climbs steeply.
        let steep: Vec<f64> = (0..k.basis_count()).map(|j| if j < 7 { 0.0 } else { 50.0 }).collect();
        let r = realise(&k, &steep, None, 30.0, 10.0, 5.0, 30.0, 1000);
        assert!(r.violations.iter().any(|v| v.contains("pressure angle")), "{:?}", r.violations);
        assert!(r.max_pressure_angle > 30.0);
        // The pressure angle matches its definition by finite differences of R(φ).
        let i = 500;
        let (a, b) = (&r.points[i - 1], &r.points[i + 1]);
        let dphi = (b.x - a.x) / r.build.gear_ratio;
        let fd = ((b.pitch_radius - a.pitch_radius) / dphi / r.points[i].pitch_radius).atan().to_degrees();
        assert!(
            (fd - r.points[i].pressure_angle).abs() < 1e-2 * (1.0 + fd.abs()),
            "{fd} vs {}",
            r.points[i].pressure_angle
        );
    }
}
