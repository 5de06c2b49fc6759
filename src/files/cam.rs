//! A cam's own files: `cams/<id>.toml` (its knots and exact coefficients, and how it is built:
//! what rebuilds its potential bit for bit) and `cams/<id>.csv` (its realised profile sampled).

use crate::elements::spline::Knots;
use crate::realise::cam::{CamBuild, FittedCam};

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
    /// Number of knots N (4 to 500, `MAX_KNOTS` of `docs/limits.md`).
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
        if f.coupling.is_empty() || f.coupling.len() > crate::limits::MAX_LINKS {
            return Err(bad(
                "coupling",
                format!("has {} entries: one per joint, at most {}", f.coupling.len(), crate::limits::MAX_LINKS),
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
        if !(4..=crate::limits::MAX_KNOTS).contains(&usize::from(f.knots)) {
            return Err(bad("knots", format!("must be 4 to {}, got {}", crate::limits::MAX_KNOTS, f.knots)));
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
