//! `[fit] max_shift`: the bound on the builds' RMS metric equilibrium shift, held as a
//! second-order cone in the QP (`fit::robust::ShiftCone`), through the library on the paper's arm.

mod util;

use springfit::asbuilt::{BuildSettings, DIRECTIONS, SAMPLES, run_builds};
use springfit::design::Design;
use springfit::design::fit::{FitSettings, MaxShift};
use springfit::design::tolerance::ToleranceSpec;
use springfit::fit::outcome::ShiftAction;
use springfit::fit::run::fit;
use springfit::progress::Progress;

/// `double_pendulum` (±5 %, 12 elements) on small fans, without the trimmed term (the cone bounds
/// the untrimmed builds' shift, which the builds below measure untrimmed).
fn quick(design: &Design, max_shift: MaxShift) -> FitSettings {
    FitSettings {
        training_directions: 24,
        training_samples: 12,
        evaluation_directions: 24,
        evaluation_samples: 12,
        trimmed_weight: 0.0,
        max_shift,
        ..design.fit
    }
}

/// Off reproduces the fit without the bound bit for bit, and so does a bound the fit meets
/// (solved once, the cone never added); a bound below the fit's shift is held by the cone to the
/// solver's tolerance, and the builds' measured RMS metric shift agrees with √(kᵀSk).
#[test]
fn the_cone_holds_the_shift_and_an_inactive_bound_changes_nothing() {
    let (design, catalog) = util::shipped("double_pendulum");
    let off = fit(&design, &catalog, &quick(&design, MaxShift::None), Progress::none()).unwrap();
    assert!(off.solve.shift_bound.is_none());
    let wide = fit(&design, &catalog, &quick(&design, MaxShift::Metric(1e9)), Progress::none()).unwrap();
    let b = wide.solve.shift_bound.clone().unwrap();
    assert_eq!(b.action, ShiftAction::Inactive);
    assert_eq!(b.rms, b.unbounded_rms);
    assert_eq!(wide.springs, off.springs, "an inactive bound must not change the fit");
    assert_eq!(wide.metrics.stats, off.metrics.stats);
    assert!(b.unbounded_rms > 0.0);

    let bound = 0.6 * b.unbounded_rms;
    let tight = fit(&design, &catalog, &quick(&design, MaxShift::Metric(bound)), Progress::none()).unwrap();
    let t = tight.solve.shift_bound.clone().unwrap();
    assert_eq!(t.action, ShiftAction::Held, "{t:?}");
    assert_eq!(t.unbounded_rms, b.unbounded_rms);
    // Clarabel's tolerance is 1e-8 on the scaled cone.
    assert!(t.rms <= bound * (1.0 + 1e-6), "√(kᵀSk) = {} against the bound {bound}", t.rms);
    // The cone is active at the optimum (the fit without it breaks it) and costs objective.
    assert!(t.rms >= bound * (1.0 - 1e-3), "√(kᵀSk) = {} well inside the bound {bound}", t.rms);
    assert!(t.objective_ratio >= 1.0 - 1e-9, "{t:?}");
    assert!(tight.metrics.equilibrium_gradient_norm < 1e-6, "{}", tight.metrics.equilibrium_gradient_norm);

    // The builds about their own equilibria: the RMS of their metric shift against the model.
    let s = BuildSettings {
        tolerance: ToleranceSpec::Fraction(0.05),
        distribution: tight.settings.distribution,
        builds: 2000,
        seed: 7,
        extent: tight.region.extent,
        directions: DIRECTIONS,
        samples: SAMPLES,
    };
    for (outcome, modelled) in [(&off, b.unbounded_rms), (&tight, t.rms)] {
        let builds = run_builds(&design, &outcome.bom, &outcome.springs, &s).unwrap();
        let shifts: Vec<f64> = builds.iter().map(|b| b.shift_metric).collect();
        assert!(shifts.iter().all(|x| x.is_finite()), "a build without an equilibrium");
        let n = shifts.len() as f64;
        let mean_square = shifts.iter().map(|x| x * x).sum::<f64>() / n;
        // Monte Carlo error of the mean square: the spread of x² over √n; 4 of them, on the RMS
        // half of that (first-order model: a small bias at ±5 % besides).
        let var = shifts.iter().map(|x| (x * x - mean_square).powi(2)).sum::<f64>() / (n - 1.0);
        let rel = 4.0 * 0.5 * var.sqrt() / n.sqrt() / mean_square + 0.02;
        let measured = mean_square.sqrt();
        assert!(
            (measured / modelled - 1.0).abs() <= rel,
            "measured RMS metric shift {measured:.5} against √(kᵀSk) = {modelled:.5} (allowed ±{:.1} %)",
            100.0 * rel
        );
    }
}

/// A bound that is negative, zero, NaN or a word other than "none" is refused naming
/// `fit.max_shift`; "none" and a positive number are read.
#[test]
fn bad_max_shift_values_are_refused_naming_the_key() {
    let path = util::repo().join("designs/double_pendulum.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let with = |value: &str| text.replacen("[fit]\n", &format!("[fit]\nmax_shift = {value}\n"), 1);
    for bad in ["-0.1", "0", "nan", "inf", "\"auto\""] {
        let e = Design::parse(&path, &with(bad)).err().unwrap_or_else(|| panic!("max_shift = {bad} accepted"));
        let msg = e.to_string();
        assert!(msg.contains("max_shift"), "max_shift = {bad}: {msg}");
    }
    let none = Design::parse(&path, &with("\"none\"")).unwrap();
    assert_eq!(none.fit.max_shift, MaxShift::None);
    let set = Design::parse(&path, &with("0.02")).unwrap();
    assert_eq!(set.fit.max_shift, MaxShift::Metric(0.02));
    let default = Design::parse(&path, &with("\"default\"")).unwrap();
    assert_eq!(default.fit.max_shift, MaxShift::Default);
    assert_eq!(Design::parse(&path, &text).unwrap().fit.max_shift, MaxShift::None);
}
