//! Cam elements: an arbitrary smooth potential V(x) = Σⱼ cⱼ Bⱼ(x) on a coupling x = a·q.
//!
//! Spring profiles with k ≥ 0 (linear, cubic, compression) are convex in x, and the exact
//! potential needs non-convex one-dimensional profiles. A disc cam with a spring-loaded roller
//! follower realises any profile bounded below, so a cam is fitted as a cubic B-spline.
//!
//! **Basis.** `count = N` uniform knots t₀ = x_lo < … < t_{N−1} = x_hi, spacing h, and N + 2
//! cardinal cubic B-splines Bⱼ(x) = B((x − x_lo)/h − (j − 1)), j = 0 … N + 1, centred on
//! t₋₁ … t_N. On [x_lo, x_hi] they sum to 1, so adding a constant to every cⱼ adds a constant to
//! V and changes no torque. **Outside the knot span** every Bⱼ continues as its second-order
//! Taylor polynomial at the nearest end: V stays C², Σⱼ Bⱼ = 1 still holds and the torque V′
//! continues along its tangent line (a linear spring beyond the span). The fit's range covers
//! every sample of the region plus a margin, so the continuation only matters when a simulation
//! leaves the region.
//!
//! **Signed coefficients, k ≥ 0.** Each basis function enters the fit twice, as +Bⱼ and −Bⱼ,
//! each with a non-negative stiffness, so cⱼ = k⁺ⱼ − k⁻ⱼ: every solver and the selection keep
//! working with k ≥ 0 and one column per candidate.
//!
//! **Smoothing.** V‴ is constant on each knot interval i: (−cᵢ + 3cᵢ₊₁ − 3cᵢ₊₂ + cᵢ₊₃)/h³, so
//! ∫ V‴² dx = Σᵢ h (Δ³c)ᵢ² / h⁶ exactly: a penalty on the torque's curvature that is a sum of
//! squares of linear forms in c, added to the least-squares problem as extra rows.

use serde::Serialize;

/// One signed B-spline basis function of a cam: which one, on which knots.
///
/// The element carrying it has `offset` = x_lo (the first knot), so its deflection d = x − x_lo.
/// The knot spacing is kept as bits so that the profile stays `Eq` and `Hash`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub struct SplineBasis {
    /// j in 0 … count + 1.
    pub index: u16,
    /// Number of knots N (≥ 4).
    pub count: u16,
    /// Knot spacing h in rad, as `f64::to_bits`.
    pub width_bits: u64,
    /// −Bⱼ instead of +Bⱼ.
    pub negative: bool,
}

impl SplineBasis {
    /// Knot spacing h in rad.
    pub fn width(self) -> f64 {
        f64::from_bits(self.width_bits)
    }

    /// Bⱼ, Bⱼ′, Bⱼ″ (derivatives in x) at deflection d = x − x_lo, with the sign applied.
    #[inline]
    pub fn eval(self, d: f64) -> (f64, f64, f64) {
        let at = SplineAt::new(self.count, self.width(), d);
        let (v, s, c) = at.basis(usize::from(self.index));
        if self.negative { (-v, -s, -c) } else { (v, s, c) }
    }

    /// Text written in the bill of materials' `side` column: `+j/N/h` or `-j/N/h` (h in Rust's
    /// shortest round-trip form, so reading it back gives the same bits).
    pub fn side_text(self) -> String {
        format!("{}{}/{}/{}", if self.negative { "-" } else { "+" }, self.index, self.count, self.width())
    }

    /// Parses [`SplineBasis::side_text`].
    pub fn parse_side(text: &str) -> Result<SplineBasis, String> {
        let bad =
            || format!("a cam basis needs side `+j/N/h` or `-j/N/h` (index, knots, spacing in rad), got \"{text}\"");
        let (negative, rest) = match text.as_bytes().first() {
            Some(b'+') => (false, &text[1..]),
            Some(b'-') => (true, &text[1..]),
            _ => return Err(bad()),
        };
        let parts: Vec<&str> = rest.split('/').collect();
        if parts.len() != 3 {
            return Err(bad());
        }
        let index: u16 = parts[0].trim().parse().map_err(|_| bad())?;
        let count: u16 = parts[1].trim().parse().map_err(|_| bad())?;
        let width: f64 = parts[2].trim().parse().map_err(|_| bad())?;
        if count < 4 || index > count + 1 || !(width.is_finite() && width > 0.0) {
            return Err(bad());
        }
        Ok(SplineBasis { index, count, width_bits: width.to_bits(), negative })
    }
}

/// Where a deflection d = x − x_lo falls on a cam's knots: the point clamped to the knot span
/// and how far beyond it d lies (shared by one basis element, [`SplineBasis::eval`], and a
/// whole cam, [`spline_sum`]).
#[derive(Debug, Clone, Copy)]
struct SplineAt {
    /// Knot spacing h.
    h: f64,
    /// d in units of h, clamped to the knot span [0, N − 1].
    end: f64,
    /// How far d lies beyond the span's nearest end, in units of h (0 inside the span).
    dt: f64,
}

impl SplineAt {
    #[inline]
    fn new(count: u16, h: f64, d: f64) -> SplineAt {
        let span = f64::from(count - 1);
        let t = d / h;
        // Inside the span the basis itself; outside, its Taylor polynomial at the nearest end.
        let end = t.clamp(0.0, span);
        SplineAt { h, end, dt: t - end }
    }

    /// Bⱼ, Bⱼ′, Bⱼ″ (derivatives in x), unsigned.
    #[inline]
    fn basis(self, index: usize) -> (f64, f64, f64) {
        let (h, dt) = (self.h, self.dt);
        let centre = index as f64 - 1.0;
        let (b, b1, b2) = cardinal(self.end - centre);
        (b + dt * (b1 + 0.5 * dt * b2), (b1 + dt * b2) / h, b2 / (h * h))
    }
}

/// V, V′, V″ at deflection d = x − x_lo of the cam V = Σⱼ cⱼ Bⱼ on `count` knots of spacing `h`
/// (`coef`: one coefficient per basis function, N + 2).
///
/// Only the four basis functions whose support holds the point clamped to the span are non-zero
/// there: with the point at u ∈ [0, 1] in knot interval i₀, Bᵢ₀₊ₘ is the m-th cubic piece
/// ((1−u)³, 3u³ − 6u² + 4, −3u³ + 3u² + 3u + 1, u³)/6. Their weighted sums are formed once, and
/// beyond the span continued as a whole along the second-order Taylor polynomial at the end (as
/// each basis function is, see the module notes). The same V as Σⱼ cⱼ [`SplineBasis::eval`] up
/// to rounding (tested), at a fraction of the cost: this is what the fit's evaluation and every
/// as-built build evaluate at each sample.
#[inline]
pub fn spline_sum(coef: &[f64], count: u16, h: f64, d: f64) -> (f64, f64, f64) {
    let at = SplineAt::new(count, h, d);
    // Interval i₀ = ⌊end⌋, the last knot counted in the last interval (u = 1).
    let i0 = if at.end.is_nan() { 0 } else { (at.end.floor() as usize).min(usize::from(count) - 2) };
    let u = at.end - i0 as f64;
    let w = 1.0 - u;
    let (u2, w2) = (u * u, w * w);
    let c = |m: usize| coef.get(i0 + m).copied().unwrap_or(0.0);
    let (c0, c1, c2, c3) = (c(0), c(1), c(2), c(3));
    // B(t) and its derivatives in t = the position in knot units.
    let b =
        (c0 * w2 * w + c1 * (3.0 * u2 * u - 6.0 * u2 + 4.0) + c2 * (3.0 * w2 * w - 6.0 * w2 + 4.0) + c3 * u2 * u) / 6.0;
    let b1 = 0.5 * (-c0 * w2 + c1 * (3.0 * u2 - 4.0 * u) - c2 * (3.0 * w2 - 4.0 * w) + c3 * u2);
    let b2 = c0 * w + c1 * (3.0 * u - 2.0) + c2 * (3.0 * w - 2.0) + c3 * u;
    let dt = at.dt;
    (b + dt * (b1 + 0.5 * dt * b2), (b1 + dt * b2) / h, b2 / (h * h))
}

/// The cardinal cubic B-spline B(t) (support [−2, 2], centred at 0) and its first two
/// derivatives in t.
#[inline]
pub fn cardinal(t: f64) -> (f64, f64, f64) {
    let a = t.abs();
    let sign = if t < 0.0 { -1.0 } else { 1.0 };
    if a < 1.0 {
        (2.0 / 3.0 - a * a + 0.5 * a * a * a, sign * (-2.0 * a + 1.5 * a * a), -2.0 + 3.0 * a)
    } else if a < 2.0 {
        let u = 2.0 - a;
        (u * u * u / 6.0, -sign * 0.5 * u * u, u)
    } else {
        (0.0, 0.0, 0.0)
    }
}

/// Uniform knots over a range of x: first knot, spacing, number of knots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Knots {
    /// First knot x_lo in rad.
    pub lo: f64,
    /// Spacing h in rad.
    pub width: f64,
    /// Number of knots N.
    pub count: u16,
}

impl Knots {
    /// `count` knots over [lo, hi] widened by `margin` (a fraction of the range) on each side.
    pub fn over(lo: f64, hi: f64, count: u16, margin: f64) -> Knots {
        let span = (hi - lo).max(1e-6);
        let (lo, hi) = (lo - margin * span, hi + margin * span);
        Knots { lo, width: (hi - lo) / f64::from(count - 1), count }
    }

    /// Last knot.
    pub fn hi(&self) -> f64 {
        self.lo + self.width * f64::from(self.count - 1)
    }

    /// Number of basis functions, N + 2.
    pub fn basis_count(&self) -> usize {
        usize::from(self.count) + 2
    }

    /// The j-th basis function with a sign.
    pub fn basis(&self, index: usize, negative: bool) -> SplineBasis {
        SplineBasis {
            index: u16::try_from(index).unwrap_or(u16::MAX),
            count: self.count,
            width_bits: self.width.to_bits(),
            negative,
        }
    }

    /// V, V′, V″ at x for coefficients c (one per basis function).
    pub fn eval(&self, c: &[f64], x: f64) -> (f64, f64, f64) {
        let mut out = (0.0, 0.0, 0.0);
        for (j, cj) in c.iter().enumerate() {
            let (v, s, k) = self.basis(j, false).eval(x - self.lo);
            out.0 += cj * v;
            out.1 += cj * s;
            out.2 += cj * k;
        }
        out
    }

    /// Rows D with ‖D c‖² = ∫ V‴(x)² dx over the knot span: N − 1 rows of N + 2 entries.
    pub fn third_derivative_rows(&self) -> Vec<Vec<f64>> {
        let h = self.width;
        let scale = (h).sqrt() / (h * h * h);
        let n = self.basis_count();
        (0..usize::from(self.count) - 1)
            .map(|i| {
                let mut row = vec![0.0; n];
                for (o, w) in [-1.0, 3.0, -3.0, 1.0].iter().enumerate() {
                    row[i + o] = w * scale;
                }
                row
            })
            .collect()
    }
}

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
    let samples = samples.max(1000);
    let (lo, hi) = (knots.lo, knots.hi());
    let xs: Vec<f64> = (0..samples).map(|i| lo + (hi - lo) * i as f64 / (samples - 1) as f64).collect();
    let vals: Vec<(f64, f64, f64)> = xs.iter().map(|&x| knots.eval(c, x)).collect();
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

/// The cams of a bill of materials: rows `Cnn.jj±` grouped by `Cnn`, coefficients summed with
/// their signs, realised with their family's settings (defaults when the family is unknown, as
/// for a bill of materials read back without its catalogue).
pub fn fitted_cams(catalog: &crate::catalog::Catalog, rows: &[crate::bom::BomRow]) -> Vec<FittedCam> {
    let mut cams = grouped(rows);
    for c in &mut cams {
        let spec = catalog.families.iter().find(|f| f.name == c.family).and_then(|f| f.cam);
        let (rate, stroke, rb, rr, alpha) = spec.map_or(DEFAULT_REALISATION, |s| {
            (s.follower_rate, s.max_stroke, s.base_radius, s.roller_radius, s.max_pressure_angle)
        });
        c.realisation = realise(&c.knots, &c.coefficients, rate, stroke, rb, rr, alpha, 1000);
    }
    cams
}

/// Follower rate, largest stroke (mm), base and roller radius (mm) and pressure-angle limit (°)
/// of a cam whose family is unknown: the catalogue's defaults.
pub const DEFAULT_REALISATION: (Option<f64>, f64, f64, f64, f64) = (None, 20.0, 40.0, 8.0, 30.0);

/// A cam realised with [`DEFAULT_REALISATION`].
pub fn realise_default(knots: &Knots, c: &[f64]) -> Realisation {
    let (rate, stroke, rb, rr, alpha) = DEFAULT_REALISATION;
    realise(knots, c, rate, stroke, rb, rr, alpha, 1000)
}

/// The cams of a bill of materials grouped as in [`fitted_cams`], in order of first appearance,
/// not yet realised (`realisation.points` empty).
pub fn grouped(rows: &[crate::bom::BomRow]) -> Vec<FittedCam> {
    let mut cams: Vec<FittedCam> = Vec::new();
    for r in rows {
        let crate::elements::Profile::Spline(b) = r.element.profile else { continue };
        let id = r.id.split('.').next().unwrap_or(&r.id).to_string();
        let pos = match cams.iter().position(|c| c.id == id) {
            Some(p) => p,
            None => {
                let knots = Knots { lo: r.element.offset, width: b.width(), count: b.count };
                cams.push(FittedCam {
                    id,
                    family: r.family.clone(),
                    coupling: r.element.coupling.clone(),
                    knots,
                    coefficients: vec![0.0; knots.basis_count()],
                    realisation: Realisation {
                        build: CamBuild {
                            follower_rate: 0.0,
                            preload: 0.0,
                            gear_ratio: 1.0,
                            base_radius: 0.0,
                            roller_radius: 0.0,
                        },
                        points: Vec::new(),
                        max_pressure_angle: 0.0,
                        min_convex_curvature: 0.0,
                        violations: Vec::new(),
                    },
                });
                cams.len() - 1
            }
        };
        let c = &mut cams[pos];
        if let Some(cj) = c.coefficients.get_mut(usize::from(b.index)) {
            *cj += if b.negative { -r.stiffness } else { r.stiffness };
        }
    }
    cams
}

/// `cams/<id>.csv`: `x_rad,potential_j,torque_nm,follower_mm,radius_mm` (radius: the pitch
/// curve's, R_b + ρ_r + s), then the pressure angle and radius of curvature.
pub fn csv(c: &FittedCam) -> String {
    let mut s =
        String::from("x_rad,potential_j,torque_nm,follower_mm,radius_mm,pressure_angle_deg,curvature_radius_mm\n");
    for p in &c.realisation.points {
        s.push_str(&format!(
            "{},{},{},{},{},{},{}\n",
            p.x, p.potential, p.torque, p.stroke, p.pitch_radius, p.pressure_angle, p.curvature_radius
        ));
    }
    s
}

/// `cams/<id>.toml`: everything needed to rebuild a cam's potential V(x) = Σⱼ cⱼ Bⱼ(x) exactly,
/// and how it is built. Written by the fit beside `cams/<id>.csv` and `.svg`, named by the cam's
/// row in `bom.csv` (column `file`), read back by every command that reads a bill of materials.
/// Numbers are written in Rust's shortest round-trip form, so reading gives the same bits.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CamFile {
    /// Coupling a (x = a·q); must equal the bill of materials' row.
    pub coupling: Vec<f64>,
    /// First knot x_lo in rad (the row's `offset_rad`).
    pub first_knot_rad: f64,
    /// Knot spacing h in rad.
    pub knot_spacing_rad: f64,
    /// Number of knots N (4 to [`crate::catalog::MAX_KNOTS`]).
    pub knots: u16,
    /// The N + 2 signed coefficients cⱼ in J, j = 0 … N + 1.
    pub coefficients_j: Vec<f64>,
    /// How the cam is built.
    pub realisation: CamFileBuild,
}

/// The `[realisation]` table of a [`CamFile`] (a [`CamBuild`] with units in its keys).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CamFileBuild {
    /// Follower spring rate k_f, N/mm (the row's `stiffness`).
    pub follower_rate_n_per_mm: f64,
    /// Follower preload p₀ at the base circle, mm.
    pub preload_mm: f64,
    /// Gear ratio g: the cam turns by (x − x_lo)/g (the row's `gear_ratio`).
    pub gear_ratio: f64,
    /// Base-circle radius R_b, mm.
    pub base_radius_mm: f64,
    /// Roller radius ρ_r, mm.
    pub roller_radius_mm: f64,
}

impl CamFileBuild {
    /// As a [`CamBuild`].
    pub fn build(&self) -> CamBuild {
        CamBuild {
            follower_rate: self.follower_rate_n_per_mm,
            preload: self.preload_mm,
            gear_ratio: self.gear_ratio,
            base_radius: self.base_radius_mm,
            roller_radius: self.roller_radius_mm,
        }
    }
}

/// A number as TOML in Rust's shortest round-trip form (`{:?}` always has a `.` or an exponent,
/// so TOML reads a float, never an integer).
fn toml_number(x: f64) -> String {
    format!("{x:?}")
}

impl CamFile {
    /// The file of a cam with coupling `coupling`, knots and coefficients, built as `build`.
    pub fn new(coupling: &[f64], knots: &Knots, coefficients: &[f64], build: &CamBuild) -> CamFile {
        CamFile {
            coupling: coupling.to_vec(),
            first_knot_rad: knots.lo,
            knot_spacing_rad: knots.width,
            knots: knots.count,
            coefficients_j: coefficients.to_vec(),
            realisation: CamFileBuild {
                follower_rate_n_per_mm: build.follower_rate,
                preload_mm: build.preload,
                gear_ratio: build.gear_ratio,
                base_radius_mm: build.base_radius,
                roller_radius_mm: build.roller_radius,
            },
        }
    }

    /// The knots.
    pub fn knot_vector(&self) -> Knots {
        Knots { lo: self.first_knot_rad, width: self.knot_spacing_rad, count: self.knots }
    }

    /// The file's text; `title` goes into the first comment line.
    pub fn to_toml(&self, title: &str) -> String {
        let list = |v: &[f64]| v.iter().map(|x| toml_number(*x)).collect::<Vec<_>>().join(", ");
        let r = &self.realisation;
        format!(
            "# springfit cam {title}\n\
             # V(x) = Σⱼ cⱼ Bⱼ(x), x = coupling·q: cubic B-splines on `knots` uniform knots from first_knot_rad\n\
             # spaced knot_spacing_rad (see docs/outputs.md). Numbers in shortest round-trip form: exact.\n\
             coupling = [{}]\n\
             first_knot_rad = {}\n\
             knot_spacing_rad = {}\n\
             knots = {}\n\
             # c_j in J, j = 0 … knots + 1\n\
             coefficients_j = [{}]\n\
             \n\
             [realisation]\n\
             follower_rate_n_per_mm = {}\n\
             preload_mm = {}\n\
             gear_ratio = {}\n\
             base_radius_mm = {}\n\
             roller_radius_mm = {}\n",
            list(&self.coupling),
            toml_number(self.first_knot_rad),
            toml_number(self.knot_spacing_rad),
            self.knots,
            list(&self.coefficients_j),
            toml_number(r.follower_rate_n_per_mm),
            toml_number(r.preload_mm),
            toml_number(r.gear_ratio),
            toml_number(r.base_radius_mm),
            toml_number(r.roller_radius_mm),
        )
    }

    /// Reads and checks a cam file: every problem names the file and the key.
    pub fn read(path: &std::path::Path) -> crate::error::Result<CamFile> {
        CamFile::parse(path, &crate::input::read_text(path)?)
    }

    /// Parses and checks the text of [`CamFile::read`].
    pub fn parse(path: &std::path::Path, text: &str) -> crate::error::Result<CamFile> {
        let f: CamFile = crate::input::parse_toml(path, text)?;
        let bad = |field: &str, reason: String| crate::error::Error::invalid(path, field, reason);
        let finite = |field: &str, x: f64| {
            if x.is_finite() { Ok(()) } else { Err(bad(field, format!("must be a finite number, got {x}"))) }
        };
        if f.coupling.is_empty() || f.coupling.len() > crate::model::MAX_LINKS {
            return Err(bad(
                "coupling",
                format!("has {} entries: one per joint, at most {}", f.coupling.len(), crate::model::MAX_LINKS),
            ));
        }
        for a in &f.coupling {
            finite("coupling", *a)?;
        }
        if f.coupling.iter().all(|a| *a == 0.0) {
            return Err(bad("coupling", "a coupling of all zeros moves nothing".into()));
        }
        finite("first_knot_rad", f.first_knot_rad)?;
        if !(f.knot_spacing_rad.is_finite() && f.knot_spacing_rad > 0.0) {
            return Err(bad(
                "knot_spacing_rad",
                format!("must be a finite spacing > 0 rad, got {}", f.knot_spacing_rad),
            ));
        }
        if !(4..=crate::catalog::MAX_KNOTS).contains(&usize::from(f.knots)) {
            return Err(bad("knots", format!("must be 4 to {}, got {}", crate::catalog::MAX_KNOTS, f.knots)));
        }
        let want = usize::from(f.knots) + 2;
        if f.coefficients_j.len() != want {
            return Err(bad(
                "coefficients_j",
                format!("has {} values, expected knots + 2 = {want} (j = 0 … {})", f.coefficients_j.len(), want - 1),
            ));
        }
        if let Some((j, c)) = f.coefficients_j.iter().enumerate().find(|(_, c)| !c.is_finite()) {
            return Err(bad("coefficients_j", format!("c_{j} = {c} is not a finite number")));
        }
        let r = &f.realisation;
        for (field, x) in [
            ("realisation.follower_rate_n_per_mm", r.follower_rate_n_per_mm),
            ("realisation.gear_ratio", r.gear_ratio),
            ("realisation.base_radius_mm", r.base_radius_mm),
            ("realisation.roller_radius_mm", r.roller_radius_mm),
        ] {
            if !(x.is_finite() && x > 0.0) {
                return Err(bad(field, format!("must be a finite number > 0, got {x}")));
            }
        }
        if !(r.preload_mm.is_finite() && r.preload_mm >= 0.0) {
            return Err(bad("realisation.preload_mm", format!("must be a finite number ≥ 0, got {}", r.preload_mm)));
        }
        Ok(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn knots() -> Knots {
        Knots::over(-1.3, 2.1, 12, 0.05)
    }

    #[test]
    fn basis_is_a_partition_of_unity_inside_and_outside_the_span() {
        let k = knots();
        let ones = vec![1.0; k.basis_count()];
        for i in 0..=400 {
            let x = k.lo - 1.0 + (k.hi() - k.lo + 2.0) * f64::from(i) / 400.0;
            let (v, s, c) = k.eval(&ones, x);
            assert!((v - 1.0).abs() < 1e-12 && s.abs() < 1e-9 && c.abs() < 1e-7, "x = {x}: {v} {s} {c}");
        }
        // A single basis function is non-negative with its peak 2/3 at its centre.
        let b = k.basis(5, false);
        assert!((b.eval(4.0 * k.width).0 - 2.0 / 3.0).abs() < 1e-14);
        assert_eq!(k.basis(5, true).eval(4.0 * k.width).0, -b.eval(4.0 * k.width).0);
    }

    #[test]
    fn derivatives_match_finite_differences_everywhere() {
        let k = knots();
        let c: Vec<f64> = (0..k.basis_count()).map(|j| ((j * 7 % 5) as f64 - 2.0) * 0.3).collect();
        let h = 1e-6;
        for i in 0..=300 {
            // Through the span and past both ends (the Taylor continuation).
            let x = k.lo - 0.7 + (k.hi() - k.lo + 1.4) * (f64::from(i) + 0.37) / 300.0;
            let (_, s, c2) = k.eval(&c, x);
            let fd1 = (k.eval(&c, x + h).0 - k.eval(&c, x - h).0) / (2.0 * h);
            let fd2 = (k.eval(&c, x + h).1 - k.eval(&c, x - h).1) / (2.0 * h);
            assert!((s - fd1).abs() < 1e-6 * (1.0 + fd1.abs()), "x = {x}: {s} vs {fd1}");
            assert!((c2 - fd2).abs() < 1e-5 * (1.0 + fd2.abs()), "x = {x}: {c2} vs {fd2}");
        }
    }

    #[test]
    fn smoothing_rows_integrate_the_third_derivative() {
        let k = knots();
        let c: Vec<f64> = (0..k.basis_count()).map(|j| (j as f64 * 0.9).sin()).collect();
        let exact: f64 =
            k.third_derivative_rows().iter().map(|r| r.iter().zip(&c).map(|(a, b)| a * b).sum::<f64>().powi(2)).sum();
        // Midpoint rule on V‴ by differences of V″ (V‴ is constant between knots).
        let steps = 20_000;
        let dx = (k.hi() - k.lo) / f64::from(steps);
        let mut integral = 0.0;
        for i in 0..steps {
            let x = k.lo + dx * (f64::from(i) + 0.5);
            let e = 1e-7;
            let v3 = (k.eval(&c, x + e).2 - k.eval(&c, x - e).2) / (2.0 * e);
            integral += v3 * v3 * dx;
        }
        assert!((integral - exact).abs() < 1e-4 * exact, "{integral} vs {exact}");
        // A quadratic has V‴ = 0: coefficients sampled from a quadratic give no penalty.
        let quad: Vec<f64> = (0..k.basis_count()).map(|j| (j as f64 - 3.0).powi(2) - 1.0 / 3.0).collect();
        let p: f64 = k
            .third_derivative_rows()
            .iter()
            .map(|r| r.iter().zip(&quad).map(|(a, b)| a * b).sum::<f64>().powi(2))
            .sum();
        assert!(p < 1e-12);
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

    /// Torque samples of a potential built from known coefficients, fitted with the ± columns
    /// and NNLS (k ≥ 0) as the fit does: the coefficients come back up to the free constant.
    #[test]
    fn known_coefficients_are_recovered_with_signed_columns() {
        use crate::solve::lsq::Gram;
        use crate::solve::nnls::{NnlsSettings, nnls};
        use nalgebra::{DMatrix, DVector};
        let k = Knots::over(-1.0, 2.0, 10, 0.0);
        let n = k.basis_count();
        let truth: Vec<f64> = (0..n).map(|j| 2.0 * (j as f64 * 1.3).sin() - 0.5).collect();
        let xs: Vec<f64> = (0..400).map(|i| -1.0 + 3.0 * f64::from(i) / 399.0).collect();
        let a = DMatrix::from_fn(xs.len(), 2 * n, |r, col| k.basis(col / 2, col % 2 == 1).eval(xs[r] - k.lo).1);
        let b = DVector::from_iterator(xs.len(), xs.iter().map(|&x| k.eval(&truth, x).1));
        let sol = nnls(&Gram::from_rows(&a, &b), 0.0, &NnlsSettings::default()).unwrap();
        let c: Vec<f64> = (0..n).map(|j| sol.k[2 * j] - sol.k[2 * j + 1]).collect();
        let shift = truth[0] - c[0];
        for j in 0..n {
            assert!((c[j] + shift - truth[j]).abs() < 1e-8, "c[{j}] = {} vs {}", c[j] + shift, truth[j]);
        }
    }

    #[test]
    fn side_text_round_trips() {
        let b = knots().basis(7, true);
        assert_eq!(SplineBasis::parse_side(&b.side_text()).unwrap(), b);
        for bad in ["", "3/12/0.1", "+3/12", "+20/12/0.1", "+3/12/-1", "+3/2/0.1", "+a/12/0.1"] {
            assert!(SplineBasis::parse_side(bad).is_err(), "{bad}");
        }
    }
}
