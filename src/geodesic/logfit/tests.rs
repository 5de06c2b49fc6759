use super::*;
use crate::geodesic::directions::MetricFrame;
use crate::geodesic::{FanSpec, Stop};
use crate::model::Link;
use crate::numerics::rng::SplitMix64;
use std::f64::consts::PI;

/// The shipped `triple_pendulum` arm (slender rods) about its bent equilibrium; its region is
/// the geodesic ball of radius 0.6.
fn triple() -> (Chain, DVector<f64>) {
    let rod = |mass: f64, length: f64| Link { mass, length, com: length / 2.0, inertia: mass * length * length / 12.0 };
    (
        Chain::new(vec![rod(1.5, 1.0), rod(1.0, 0.8), rod(0.5, 0.6)], [0.0, -9.81]),
        DVector::from_vec(vec![-PI / 3.0, PI / 4.0, PI / 4.0]),
    )
}

/// `count` points v of metric length in [0.05, 1] × `radius`, uniform in direction.
fn random_velocities(frame: &MetricFrame, n: usize, radius: f64, count: usize) -> Vec<DVector<f64>> {
    let mut rng = SplitMix64::new(47);
    (0..count)
        .map(|_| {
            let u = DVector::from_iterator(n, (0..n).map(|_| rng.normal())).normalize();
            let r = radius * (0.05 + 0.95 * rng.uniform());
            frame.to_joint(&u) * r
        })
        .collect()
}

#[test]
fn monomials_are_counted_once() {
    for (n, d) in [(2, 3), (3, 8), (6, 4)] {
        assert_eq!(monomials(n, d).len(), monomial_count(n, d));
    }
    // The default degrees stay within the budget of terms.
    assert_eq!(LogFitSpec::for_joints(3, 1.0).degree, 8);
    assert_eq!(LogFitSpec::for_joints(6, 1.0).degree, 4);
}

#[test]
fn the_fitted_label_matches_the_exact_log_map_inside_the_region() {
    let (chain, q_eq) = triple();
    let ode = OdeSettings::default();
    // Half the shipped design's radius: the fit's error there is 0.02° (0.37° at 0.45 and 2.6°
    // at 0.6, where the arm's joints turn by radians: `auto` keeps the exact label there).
    let radius = 0.3;
    let mut fit = LogFit::build(&chain, &q_eq, ode, LogFitSpec::for_joints(3, radius)).unwrap();
    let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
    // The reported error, on a held-out fan.
    let fan =
        Fan::trace(&chain, &q_eq, FanSpec { count: 120, phase: 0.5, stop: Stop::Arc(radius), spacing: 0.03 }, ode)
            .unwrap();
    let (err, count) = fit.label_error(&frame, &fan, 0.03).unwrap();
    assert!(count > 1000 && err < 0.05, "label error {err}° on {count}");
    // Random points q = exp(v) inside the ball: the fitted log against Newton shooting (value
    // and ∂v/∂q), and exp of the fitted log back to q.
    let mut exact = ExactLog::new(&chain, &q_eq, ode);
    let mut shooter = Shooter::new(&chain, &q_eq, ode);
    let (mut a, mut b) = (LogValue::zeros(3), LogValue::zeros(3));
    let mut worst_angle: f64 = 0.0;
    for v in random_velocities(&frame, 3, radius, 200) {
        let q = shooter.exp(&v).unwrap();
        fit.eval(q.as_slice(), &mut a).unwrap();
        exact.eval(q.as_slice(), &mut b).unwrap();
        let r = v.dot(&(chain.mass_matrix(&q_eq) * &v)).sqrt();
        let (wa, wb) =
            (frame.to_frame(&DVector::from_column_slice(&a.v)), frame.to_frame(&DVector::from_column_slice(&b.v)));
        // Relative to the distance from q_eq: what the label's angle sees.
        assert!((&wa - &wb).norm() < 1e-3 * r, "v {:?} vs {:?} at r = {r}", a.v, b.v);
        worst_angle = worst_angle.max(2.0 * (wa.normalize() - wb.normalize()).norm().asin().to_degrees());
        let scale = b.dvdq.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for k in 0..9 {
            assert!((a.dvdq[k] - b.dvdq[k]).abs() < 2e-2 * scale, "∂v/∂q {k}: {} vs {}", a.dvdq[k], b.dvdq[k]);
        }
        let back = shooter.exp(&DVector::from_column_slice(&a.v)).unwrap();
        // In joint angles, relative to the displacement from q_eq.
        let dq = (&q - &q_eq).amax();
        assert!((&back - &q).amax() < 2e-3 * dq, "exp(log q) − q = {:e} at |q − q_eq| = {dq}", (&back - &q).amax());
    }
    assert!(worst_angle < 0.05, "{worst_angle}°");
}

#[test]
fn beyond_its_ball_the_fit_answers_with_the_exact_log_map() {
    let (chain, q_eq) = triple();
    let ode = OdeSettings::default();
    let mut fit = LogFit::build(&chain, &q_eq, ode, LogFitSpec::for_joints(3, 0.3)).unwrap();
    let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
    let mut shooter = Shooter::new(&chain, &q_eq, ode);
    let v = frame.to_joint(&DVector::from_vec(vec![0.0, 0.6, 0.8])) * 0.5;
    let q = shooter.exp(&v).unwrap();
    let mut out = LogValue::zeros(3);
    assert!(!fit.fitted(q.as_slice(), &mut out));
    fit.eval(q.as_slice(), &mut out).unwrap();
    assert!((DVector::from_column_slice(&out.v) - &v).amax() < 1e-8);
}

#[test]
fn the_build_does_not_depend_on_the_thread_count() {
    let (chain, q_eq) = triple();
    let spec = LogFitSpec::for_joints(3, 0.6);
    let build = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| match LogFit::build(&chain, &q_eq, OdeSettings::default(), spec).unwrap().model {
            Model::Global { coef, .. } => coef,
            Model::Cells { .. } => unreachable!("LogFit::build fits one polynomial"),
        })
    };
    assert_eq!(build(1), build(2));
}
