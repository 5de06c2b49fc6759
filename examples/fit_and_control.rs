//! From a design file to a controlled arm, in Rust: load the default design, fit its springs,
//! read the bill of materials, then run the paper's energy controller on the fitted springs,
//! integrating the arm here (a robot's own loop would call `Controller::torque` the same way).
//!
//! ```sh
//! cargo run --release --example fit_and_control
//! cargo run --release --example fit_and_control -- designs/triple_pendulum.toml swingup
//! ```
//!
//! The second argument names a `[[scenario]]` of the design (default `swingup`): its first run
//! gives the start, the joint damping and the controllers' targets.

use springfit::dynamics::control::ElasticPotential;
use springfit::dynamics::scenario::{label_source, resolve_scenario};
use springfit::{Controller, Design, FitJob, FitRequest, Progress};

fn main() -> springfit::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| "designs/double_pendulum.toml".into());
    let scenario = args.next().unwrap_or_else(|| "swingup".into());

    // 1. The design, checked, and its fit (what `springfit fit` runs, without writing files).
    let design = Design::load(path.as_ref())?;
    let checked = springfit::validate(&design)?;
    let run = FitJob::new(&design, checked.catalog.as_ref(), FitRequest::default())?.run(Progress::none())?;
    let stats = &run.outcome.metrics.stats;
    println!(
        "{}: {} springs, residual angle median {:.3}°, p99 {:.3}°",
        design.name,
        run.outcome.used(),
        stats.median_abs,
        stats.p99_abs
    );

    // 2. The bill of materials: one row per element, its stiffness and its preload at q_eq.
    for row in &run.outcome.bom {
        let preload = row.preload_nm.map(|p| format!("{p:+.2} N·m")).unwrap_or_default();
        println!("  {:<8} {:<22} k = {:>10.4}  {preload}", row.id, row.family, row.stiffness);
    }

    // 3. The controller on the fitted springs, with the scenario's targets.
    let index = design.scenarios.iter().position(|s| s.name == scenario).ok_or_else(|| springfit::Error::Setting {
        field: "scenario".into(),
        reason: format!("{} has no [[scenario]] named `{scenario}`", design.path.display()),
    })?;
    let potential = ElasticPotential::Springs(run.outcome.springs.clone());
    let (label, _) = label_source(&design, &design.simulate)?;
    let spec = resolve_scenario(&design, &potential, &label, index)?.runs.swap_remove(0);
    let mut controller =
        Controller::new(&design.chain, &design.q_eq, &potential, design.controllers.clone(), Some(label.field()))?;
    controller.set_damping(spec.damping.clone());
    controller.set_mode(spec.mode.clone());
    controller.set_energy(spec.energy.clone());
    let target = spec.energy.as_ref().map(|e| e.target(spec.duration));

    // 4. The arm in the loop: M q̈ + h(q, q̇) = τ_motor − ∇U_springs − ∇U_gravity − D q̇, by the
    //    classical Runge–Kutta method at 1 kHz, the motor torque held over each step as a
    //    digital controller holds it.
    let (n, dt) = (design.dof(), 1e-3);
    let (mut q, mut qd) = (spec.q0.clone(), spec.qd0.clone());
    let mut ws = design.chain.workspace();
    let springs = &run.outcome.springs;
    let mut rhs = |q: &[f64], qd: &[f64], motor: &[f64], qdd: &mut [f64]| {
        let (mut elastic, mut gravity) = (vec![0.0; n], vec![0.0; n]);
        springs.gradient_into(q, &mut elastic);
        design.chain.gravity_gradient_into(q, &mut gravity);
        let tau: Vec<f64> = (0..n).map(|i| motor[i] - elastic[i] - gravity[i] - spec.damping[i] * qd[i]).collect();
        design.chain.acceleration(&mut ws, q, qd, &tau, qdd)
    };
    let (mut energy, mut peak) = (f64::NAN, 0.0_f64);
    let steps = (spec.duration / dt).round() as usize;
    for step in 0..steps {
        let out = controller.torque(step as f64 * dt, &q, &qd)?;
        let motor: Vec<f64> = (0..n).map(|i| out.motor(i)).collect();
        peak = motor.iter().fold(peak, |m, t| m.max(t.abs()));
        energy = out.energy_value;
        let mut k = [vec![0.0; 2 * n], vec![0.0; 2 * n], vec![0.0; 2 * n], vec![0.0; 2 * n]];
        for s in 0..4 {
            let h = [0.0, 0.5, 0.5, 1.0][s] * dt;
            let prev = if s == 0 { vec![0.0; 2 * n] } else { k[s - 1].clone() };
            let qs: Vec<f64> = (0..n).map(|i| q[i] + h * prev[i]).collect();
            let qds: Vec<f64> = (0..n).map(|i| qd[i] + h * prev[n + i]).collect();
            let (dq, dqd) = k[s].split_at_mut(n);
            dq.copy_from_slice(&qds);
            if !rhs(&qs, &qds, &motor, dqd) {
                return Err(springfit::Error::Setting {
                    field: "scenario".into(),
                    reason: format!("the mass matrix is singular at t = {:.3} s", step as f64 * dt),
                });
            }
        }
        for i in 0..2 * n {
            let d = dt / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
            if i < n { q[i] += d } else { qd[i - n] += d }
        }
    }
    match target {
        Some(e_d) => println!(
            "scenario {scenario}: after {:.0} s the energy is {energy:.2} J (target {e_d:.2} J); peak motor torque {peak:.2} N·m",
            spec.duration
        ),
        None => println!("scenario {scenario}: after {:.0} s, peak motor torque {peak:.2} N·m", spec.duration),
    }
    Ok(())
}
