//! The window design's cams within their pressure angle (issue 44): the base circle of
//! `catalogs/cams_paper.toml` is what holds them, and it changes no part.
//!
//! The fixture is cam C04 of `designs/double_pendulum_paper_window_built.toml`'s fit as shipped
//! (`cams/C04.toml` of `springfit --threads 1 fit`), the cam the mass weight steepens most. Its
//! steepest point is the end of its knot span, past the region's range of x = q₁ − q₂ (the
//! catalogue's `margin`), where the follower leaves the base circle: there tan α = R′/R with
//! R = R_b + ρ_r, and R′ = g·ds/dx does not depend on R_b (the follower's rate is set by the cam's
//! range and the family's stroke). So a larger base circle divides tan α by (R_b′ + ρ_r)/(R_b + ρ_r)
//! and leaves the follower, its preload and every stroke as they were.

use std::path::PathBuf;

use springfit::elements::catalog::Catalog;
use springfit::files::cam::CamFile;
use springfit::realise::cam::{Realisation, realise};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The window design's C04 realised with the catalogue's cam settings, the base circle replaced
/// by `base_radius` if given.
fn c04(base_radius: Option<f64>) -> (Realisation, f64) {
    let catalog = Catalog::load(&repo().join("catalogs/cams_paper.toml"), 2).unwrap();
    let spec = catalog.families.iter().find_map(|f| f.cam).unwrap();
    let cam = CamFile::read(&repo().join("tests/data/window_built_C04.toml")).unwrap();
    let rb = base_radius.unwrap_or(spec.base_radius);
    let r = realise(
        &cam.knot_vector(),
        &cam.coefficients_j,
        spec.follower_rate,
        spec.max_stroke,
        spec.preload_fraction,
        rb,
        spec.roller_radius,
        spec.max_pressure_angle,
        1000,
    );
    (r, spec.max_pressure_angle)
}

#[test]
fn the_catalogues_base_circle_keeps_the_window_cams_within_their_pressure_angle() {
    let (r, limit) = c04(None);
    assert!(r.violations.is_empty(), "{:?}", r.violations);
    assert!(r.max_pressure_angle <= limit, "{} > {limit}", r.max_pressure_angle);
    // The fixture is the cam written by the fit: the same build.
    let cam = CamFile::read(&repo().join("tests/data/window_built_C04.toml")).unwrap();
    assert_eq!(r.build, cam.realisation.build());
    // On the 120 mm base circle the catalogue had before, the same cam is past its limit.
    let (small, _) = c04(Some(120.0));
    assert!(small.max_pressure_angle > limit, "{}", small.max_pressure_angle);
    assert!(small.violations.iter().any(|v| v.contains("pressure angle")), "{:?}", small.violations);
}

#[test]
fn the_base_circle_changes_the_pressure_angle_and_no_part() {
    let (large, _) = c04(None);
    let (small, _) = c04(Some(120.0));
    // The follower is the same part: rate, preload, gear and every stroke.
    let (a, b) = (large.build, small.build);
    assert_eq!((a.follower_rate, a.preload, a.gear_ratio), (b.follower_rate, b.preload, b.gear_ratio));
    for (p, q) in large.points.iter().zip(&small.points) {
        assert_eq!((p.x, p.potential, p.stroke), (q.x, q.potential, q.stroke));
        // R′ = R tan α is the same on both circles; only R differs, by the base radii's difference.
        let (rp, rq) = (
            p.pitch_radius * p.pressure_angle.to_radians().tan(),
            q.pitch_radius * q.pressure_angle.to_radians().tan(),
        );
        assert!((rp - rq).abs() <= 1e-9 * (1.0 + rp.abs()), "R′ {rp} vs {rq} at x = {}", p.x);
        assert!((p.pitch_radius - q.pitch_radius - (a.base_radius - 120.0)).abs() < 1e-9);
    }
    // The steepest point is where the follower is on the base circle at the span's end, outside
    // the region's range of x = q₁ − q₂ (−7 … 5 rad): there tan α scales by (120 + ρ_r)/(R_b + ρ_r).
    let steepest =
        large.points.iter().max_by(|p, q| p.pressure_angle.abs().total_cmp(&q.pressure_angle.abs())).unwrap();
    assert!(steepest.x > 5.0 || steepest.x < -7.0, "{steepest:?}");
    let within =
        large.points.iter().filter(|p| (-7.0..=5.0).contains(&p.x)).map(|p| p.pressure_angle.abs()).fold(0.0, f64::max);
    assert!(
        within < 0.5 * large.max_pressure_angle,
        "{within} inside the region, {} at its end",
        large.max_pressure_angle
    );
}
