//! Closed-loop simulation through the library: conservation, the exact potential's modes, the
//! controllers reaching their targets, and the mode controller on three joints.

use std::path::Path;

use nalgebra::DVector;
use springfit::design::Design;
use springfit::design::controllers::{Blend, ControllerSettings};
use springfit::design::scenario::{EnergyTarget, ModeSpec, ScenarioKind};
use springfit::design::simulate::SimSettings;
use springfit::dynamics::backbone::{backbone, backbone_energies};
use springfit::dynamics::scenario::{label_source, metrics, run_scenario, start_on_mode};
use springfit::dynamics::simulate::{Dynamics, ElasticPotential, ModeControl, ModeTarget, RunSpec, run};
use springfit::elements::catalog::Catalog;
use springfit::fit::run::fit;
use springfit::geodesic::MetricFrame;
use springfit::geodesic::label::ExactLog;

fn design(name: &str) -> Design {
    Design::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("designs").join(name)).unwrap()
}

fn fitted(d: &Design) -> ElasticPotential {
    let catalog = Catalog::load(d.catalog.as_ref().unwrap(), d.dof()).unwrap();
    ElasticPotential::Springs(fit(d, &catalog, &d.fit, springfit::progress::Progress::none()).unwrap().springs)
}

fn scenario_index(d: &Design, name: &str) -> usize {
    d.scenarios.iter().position(|s| s.name == name).unwrap()
}

#[test]
fn energy_is_conserved_without_damping_and_control() {
    let d = design("double_pendulum_workshop.toml");
    let pot = fitted(&d);
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let out = run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, scenario_index(&d, "free")).unwrap();
    assert_eq!(out.runs.len(), 6);
    for (r, m) in &out.runs {
        assert_eq!(r.trace.t.last().copied().unwrap(), 20.0);
        let drift = m.energy_drift_rel.unwrap();
        assert!(drift <= 1e-6, "{}: relative energy drift {drift}", r.name);
        assert_eq!(m.flux.mode + m.flux.energy + m.flux.damping, 0.0);
    }
}

#[test]
fn the_exact_potential_keeps_every_release_on_its_mode() {
    let d = design("double_pendulum.toml");
    let pot = ElasticPotential::Exact { omega: d.fit.frequency };
    let (label, err) = label_source(&d, &d.simulate).unwrap();
    assert!(err.unwrap().0 < 1e-3, "label table error {:?}", err);
    let out = run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, scenario_index(&d, "free")).unwrap();
    for (r, m) in &out.runs {
        let drift = m.mode_drift_deg.unwrap();
        assert!(drift < 0.01, "{}: mode drift {drift}°", r.name);
        // The headline figure: q(t) stays on the geodesic through q_eq and the start.
        let dev = m.geodesic_deviation.as_ref().unwrap();
        assert!(dev.max <= 1e-4, "{}: geodesic deviation {:e}", r.name, dev.max);
        assert!((dev.start_radius - 1.118).abs() < 0.01, "{}: r₀ = {}", r.name, dev.start_radius);
        // 20 s at ω = 4 rad/s: 2·20/(2π/4) ≈ 25.5 swings from one side of q_eq to the other.
        assert!((25..=27).contains(&dev.per_swing.len()), "{}: {} swings", r.name, dev.per_swing.len());
        assert_eq!(r.trace.geodesic_deviation.len(), r.trace.t.len());
    }
}

#[test]
fn twelve_springs_leave_the_geodesic_by_a_bounded_amount() {
    let d = design("double_pendulum.toml");
    let pot = fitted(&d);
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let out = run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, scenario_index(&d, "free")).unwrap();
    let mut worst: f64 = 0.0;
    for (r, m) in &out.runs {
        let dev = m.geodesic_deviation.as_ref().unwrap();
        // 0.39° p99 residual (12 springs around 3 trims): visibly off the mode, by a few per
        // cent of the amplitude per swing; the worst release (mode 4π/3) drifts by 22 % of its
        // start radius over the 20 s (12.7 periods), the others by less.
        assert!(dev.max > 1e-3 && dev.max_rel < 0.25, "{}: {dev:?}", r.name);
        // Deviation grows swing by swing from nothing at the release.
        assert!(dev.per_swing[0] < dev.max, "{}: {:?}", r.name, dev.per_swing);
        worst = worst.max(dev.max);
    }
    println!("12 springs: largest geodesic deviation {worst:.4e} √(kg·m²)·rad");
}

#[test]
fn a_saturated_swing_up_still_reaches_its_target_energy() {
    // The exact potential (no fit), actuators limited to 2 N·m: τ_E + compensation saturates for
    // a good part of the swing-up from 5 J to 20 J against D = 0.3 I, gets there all the same,
    // and never exceeds the limit.
    let d = design("double_pendulum.toml");
    let pot = ElasticPotential::Exact { omega: d.fit.frequency };
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let mut limited = d.clone();
    limited.scenarios[scenario_index(&d, "swingup")].variants = vec!["energy_compensated".into()];
    let controllers = ControllerSettings { max_torque: Some(vec![2.0, 2.0]), ..d.controllers.clone() };
    let out = run_scenario(&limited, &pot, &label, &d.simulate, &controllers, scenario_index(&d, "swingup")).unwrap();
    let m = &out.runs[0].1;
    println!(
        "limited swing-up: E − E_d {:+.4} %, saturated {:.2} s, peak {:.4} N·m (asked {:.3})",
        100.0 * m.energy_signed_error_last5s.unwrap(),
        m.saturated_s,
        m.peak_actuator_torque_nm,
        m.peak_demanded_torque_nm
    );
    assert!(m.saturated_s > 1.0, "{m:?}");
    assert!(m.peak_actuator_torque_nm <= 2.0 + 1e-9, "{m:?}");
    assert!(m.energy_rel_error_last5s.unwrap() < 0.01, "{m:?}");
}

#[test]
fn the_exact_potential_is_isochronous_on_every_mode_and_energy() {
    // ½ω²r²: r(t) = r₀ cos ωt on every geodesic, so T = 2π/ω whatever the mode and the energy.
    // Two modes at the design's lowest and highest backbone energies (5 and 20 J).
    let d = design("double_pendulum.toml");
    let pot = ElasticPotential::Exact { omega: d.fit.frequency };
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let energies = backbone_energies(&d);
    assert_eq!(energies, vec![5.0, 10.0, 15.0, 20.0]);
    let modes = [ModeSpec::Angle(0.0), ModeSpec::Angle(4.0 * std::f64::consts::FRAC_PI_3)];
    let b = backbone(&d, &pot, &label, &d.simulate, &modes, &[energies[0], energies[3]]).unwrap();
    assert_eq!(b.points.len(), 4);
    assert!(b.out_of_reach.is_empty());
    let err = b.isochrony_error.unwrap();
    println!("exact potential: isochrony error {err:.3e} over {} points", b.points.len());
    assert!(err < 1e-6, "{b:?}");
    assert!((b.nominal_period_s - 2.0 * std::f64::consts::PI / 4.0).abs() < 1e-15);
}

#[test]
fn controllers_reach_their_targets_with_fitted_springs() {
    let d = design("double_pendulum.toml");
    let pot = fitted(&d);
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let swing = run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, scenario_index(&d, "swingup")).unwrap();
    let by = |name: &str| swing.runs.iter().find(|(r, _)| r.name == name).unwrap().1.clone();
    let compensated = by("energy_compensated");
    assert!(compensated.energy_rel_error_last5s.unwrap() < 0.02, "{compensated:?}");
    // τ_E alone leaves a deficit against joint damping.
    assert!(by("energy").energy_signed_error_last5s.unwrap() < -0.005);
    // The mode controller blended in smoothly (the default) reaches every target of the switch
    // scenario, and τ_E holds the start energy (energy_target = "hold", the default).
    assert_eq!(d.controllers.blend, Blend::Smooth);
    let index = scenario_index(&d, "switch");
    let switch = run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, index).unwrap();
    let (r, m) = &switch.runs[0];
    assert_eq!(m.settling_s.len(), 7);
    for (k, s) in m.settling_s.iter().enumerate() {
        assert!(s.is_some_and(|s| s < 10.0), "mode step {k} settles in {s:?}");
    }
    assert!(m.energy_rel_error_last5s.unwrap() < 0.02, "{m:?}");
    // 100 s at 1 kHz sampled every 10 ms: 10 001 samples on the grid, the last at 100 s.
    assert_eq!(r.trace.t.len(), 10_001);
    assert_eq!(*r.trace.t.last().unwrap(), 100.0);
    assert!(r.trace.t.iter().enumerate().all(|(j, &t)| t == j as f64 / 100.0));
    // Within the paper's ±10 N·m (the design's max_torque), saturated for a while, every step
    // still settles within 4 s.
    assert_eq!(d.controllers.max_torque.as_deref(), Some(&[10.0, 10.0][..]));
    println!(
        "switch: peak {:.3} N·m (asked {:.3}), saturated {:.3} s, share {:.4} %, settling {:?}",
        m.peak_actuator_torque_nm,
        m.peak_demanded_torque_nm,
        m.saturated_s,
        100.0 * m.actuator_share,
        m.settling_s
    );
    assert!(m.peak_actuator_torque_nm <= 10.0 + 1e-9 && m.peak_demanded_torque_nm > 10.0, "{m:?}");
    assert!(m.saturated_s > 0.0 && m.saturated_s < 5.0, "{m:?}");
    assert!(m.settling_s.iter().all(|s| s.is_some_and(|s| s < 4.0)), "{:?}", m.settling_s);
    // The paper's hard switch kicks harder after each mode step (both without a limit).
    let unlimited = ControllerSettings { max_torque: None, ..d.controllers.clone() };
    let smooth_run = run_scenario(&d, &pot, &label, &d.simulate, &unlimited, index).unwrap();
    let hard = ControllerSettings { blend: Blend::Hard, ..unlimited };
    let hard_run = run_scenario(&d, &pot, &label, &d.simulate, &hard, index).unwrap();
    let (smooth_peak, hard_peak) = (smooth_run.runs[0].1.peak_torque_nm.mode, hard_run.runs[0].1.peak_torque_nm.mode);
    assert_eq!(smooth_run.runs[0].1.saturated_s, 0.0);
    println!("peak mode torque: smooth blend {smooth_peak:.2} N·m, hard switch {hard_peak:.2} N·m");
    assert!(smooth_peak < 0.9 * hard_peak, "smooth {smooth_peak} N·m, hard {hard_peak} N·m");
    // Without an energy target the mode controller's damping drains the swing.
    let mut none = d.clone();
    none.scenarios[index].energy_target = Some(EnergyTarget::None);
    let faded = run_scenario(&none, &pot, &label, &d.simulate, &d.controllers, index).unwrap();
    let (rf, mf) = &faded.runs[0];
    assert!(mf.energy_rel_error_last5s.is_none() && mf.flux.energy == 0.0);
    let (e0, e1) = (rf.trace.energy[0], *rf.trace.energy.last().unwrap());
    println!("energy_target = none: E from {e0:.2} J to {e1:.2} J; hold: to {:.2} J", r.trace.energy.last().unwrap());
    assert!(e1 < 0.8 * e0, "E from {e0} to {e1} J");
    assert!(faded.scenario.energy_handling.contains("none") && switch.scenario.energy_handling.contains("hold"));
}

#[test]
fn the_mode_controller_turns_a_three_joint_arm_onto_the_desired_mode() {
    let d = design("triple_pendulum.toml");
    let pot = ElasticPotential::Exact { omega: d.fit.frequency };
    let frame = MetricFrame::new(&d.chain.mass_matrix(&d.q_eq)).unwrap();
    let unit = |v: [f64; 3]| {
        let v = DVector::from_vec(v.to_vec());
        let len = frame.to_frame(&v).norm();
        v / len
    };
    let (u0, u1) = (unit([1.0, -1.0, 0.5]), unit([1.0, -0.6, 0.9]));
    let mut exact = ExactLog::new(&d.chain, &d.q_eq, d.geodesics.ode);
    let mut lv = springfit::geodesic::label::LogValue::zeros(3);
    let m_eq = d.chain.mass_matrix(&d.q_eq);
    let omega = d.fit.frequency;
    let mut energy_at = |q: &[f64]| -> springfit::Result<f64> {
        use springfit::geodesic::label::LogField;
        exact.eval(q, &mut lv)?;
        let v = DVector::from_column_slice(&lv.v);
        Ok(0.5 * omega * omega * v.dot(&(&m_eq * &v)))
    };
    let q0 = start_on_mode(&d, &u0, 2.0, &mut energy_at).unwrap();
    let target = frame.to_frame(&u1).normalize();
    let spec = RunSpec {
        name: "turn".into(),
        q0,
        qd0: vec![0.0; 3],
        duration: 8.0,
        damping: vec![0.0; 3],
        mode: Some(ModeControl { schedule: vec![(0.0, ModeTarget::Direction(target))] }),
        energy: None,
        parasitic: None,
        stiffness_scale: None,
        built: None,
    };
    let settings = SimSettings { rate: 400.0, ..d.simulate };
    let controllers = ControllerSettings { k_theta: 5.0, ..d.controllers.clone() };
    let field = Box::new(ExactLog::new(&d.chain, &d.q_eq, d.geodesics.ode));
    let mut dynamics = Dynamics::new(&d.chain, &d.q_eq, &pot, controllers.clone(), &spec, Some(field)).unwrap();
    let result = run(&mut dynamics, &settings).unwrap();
    let labels: Vec<f64> = result.trace.label.iter().copied().filter(|v| v.is_finite()).collect();
    let (first, last) = (labels[0].to_degrees(), labels.last().unwrap().to_degrees());
    assert!(first > 20.0, "starts {first}° from the desired mode");
    assert!(last < 2.0, "ends {last}° from the desired mode");
    let m = metrics(&result, &spec, &controllers, ScenarioKind::Switch);
    assert!(m.flux.mode > 0.0);
}

#[test]
fn the_adaptive_integrator_agrees_with_rk4_and_reports_underflow() {
    use springfit::design::simulate::Integrator;
    use springfit::numerics::ode::OdeSettings;
    let d = design("double_pendulum_workshop.toml");
    let pot = fitted(&d);
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let free = scenario_index(&d, "free");
    let rk4 = run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, free).unwrap();
    let adaptive_settings = SimSettings { integrator: Integrator::Adaptive, ..d.simulate };
    let adaptive = run_scenario(&d, &pot, &label, &adaptive_settings, &d.controllers, free).unwrap();
    for ((a, ma), (b, _)) in adaptive.runs.iter().zip(&rk4.runs) {
        assert!(ma.energy_drift_rel.unwrap() < 1e-6, "{}: {:?}", a.name, ma.energy_drift_rel);
        let (qa, qb) = (&a.trace.q, &b.trace.q);
        assert_eq!(qa.len(), qb.len());
        let diff = qa.iter().zip(qb).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        assert!(diff < 1e-5, "{}: adaptive and RK4 differ by {diff}", a.name);
    }
    // A step-size floor the dynamics cannot respect is reported with the run and the time.
    let broken = SimSettings {
        integrator: Integrator::Adaptive,
        ode: OdeSettings { rtol: 1e-12, atol: 1e-14, min_step: 0.05, ..OdeSettings::default() },
        ..d.simulate
    };
    let err = run_scenario(&d, &pot, &label, &broken, &d.controllers, free).err().expect("underflow").to_string();
    assert!(err.contains("scenario free run release_") && err.contains("step size underflow at t ="), "{err}");
}

#[test]
fn energy_targets_follow_a_schedule() {
    let base =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/double_pendulum_workshop.toml"))
            .unwrap();
    let catalog = Path::new(env!("CARGO_MANIFEST_DIR")).join("catalogs/workshop.toml");
    let text = base
        .replace("../catalogs/workshop.toml", catalog.to_str().unwrap())
        .replace("ed = 20.0", "ed = [[0.0, 12.0], [10.0, 20.0]]");
    let path = std::env::temp_dir().join(format!("springfit-schedule-{}.toml", std::process::id()));
    std::fs::write(&path, text).unwrap();
    let d = Design::load(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let out = run_scenario(
        &d,
        &ElasticPotential::Exact { omega: d.fit.frequency },
        &label,
        &d.simulate,
        &d.controllers,
        scenario_index(&d, "swingup"),
    )
    .unwrap();
    let (r, m) = out.runs.iter().find(|(r, _)| r.name == "energy_compensated").unwrap();
    let at = |time: f64| {
        let k = r.trace.t.iter().position(|&t| t >= time).unwrap();
        r.trace.energy[k]
    };
    assert!((at(9.5) - 12.0).abs() < 0.5, "E(9.5 s) = {}", at(9.5));
    assert!(m.energy_rel_error_last5s.unwrap() < 0.02, "{m:?}");
}
