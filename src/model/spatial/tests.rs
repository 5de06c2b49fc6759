//! Tests of `spatial`.

use super::*;
use crate::model::{Link, PlanarChain};

/// Deterministic points in [-1, 1]ⁿ.
pub(crate) fn points(n: usize, count: usize, seed: u64) -> Vec<DVector<f64>> {
    let mut state = 0x9E37_79B9_7F4A_7C15_u64 ^ seed;
    (0..count)
        .map(|_| {
            DVector::from_fn(n, |_, _| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state as f64 / u64::MAX as f64) * 2.0 - 1.0
            })
        })
        .collect()
}

/// A planar chain as a spatial one: z axes, each joint at the previous link's end on its
/// x axis, centres of mass on the x axes, the same gravity vector.
pub(crate) fn planar_as_spatial(links: &[Link], gravity: [f64; 2]) -> SpatialChain {
    let bodies = links
        .iter()
        .enumerate()
        .map(|(i, l)| Body {
            joint: format!("joint{}", i + 1),
            rotation: Matrix3::identity(),
            translation: if i == 0 { Vector3::zeros() } else { Vector3::new(links[i - 1].length, 0.0, 0.0) },
            axis: Vector3::z(),
            mass: l.mass,
            com: Vector3::new(l.com, 0.0, 0.0),
            // Off-plane inertias do not enter planar motion: give them values anyway.
            inertia: Matrix3::new(0.3, 0.01, 0.02, 0.01, 0.4, 0.03, 0.02, 0.03, l.inertia)
                .map(|x| x * if l.inertia > 0.0 { 1.0 } else { 0.0 }),
        })
        .collect();
    let last = links[links.len() - 1].length;
    SpatialChain::new(bodies, [gravity[0], gravity[1], 0.0], [last, 0.0, 0.0])
}

fn three_links() -> Vec<Link> {
    vec![
        Link { mass: 1.3, length: 1.1, com: 0.4, inertia: 0.2 },
        Link { mass: 0.7, length: 0.9, com: 0.5, inertia: 0.05 },
        Link { mass: 0.4, length: 0.6, com: 0.35, inertia: 0.02 },
    ]
}

/// A chain with skew axes, offsets and full inertia tensors, for the derivative tests.
pub(crate) fn skew_arm() -> SpatialChain {
    let rot = |r: f64, p: f64, y: f64| *nalgebra::Rotation3::from_euler_angles(r, p, y).matrix();
    let inertia = |a: f64, b: f64, c: f64, d: f64| Matrix3::new(a, d, 0.01, d, b, -0.02, 0.01, -0.02, c);
    let bodies = vec![
        Body {
            joint: "a".into(),
            rotation: rot(0.1, 0.0, 0.3),
            translation: Vector3::new(0.0, 0.0, 0.3),
            axis: Vector3::z(),
            mass: 3.0,
            com: Vector3::new(0.02, 0.01, 0.1),
            inertia: inertia(0.05, 0.06, 0.04, 0.005),
        },
        Body {
            joint: "b".into(),
            rotation: rot(0.0, 1.2, 0.0),
            translation: Vector3::new(0.0, 0.12, 0.05),
            axis: Vector3::new(0.0, 1.0, 0.2).normalize(),
            mass: 2.0,
            com: Vector3::new(0.0, 0.0, 0.25),
            inertia: inertia(0.12, 0.11, 0.03, 0.004),
        },
        Body {
            joint: "c".into(),
            rotation: rot(-0.4, 0.2, 0.7),
            translation: Vector3::new(0.0, -0.1, 0.4),
            axis: Vector3::new(0.3, 1.0, 0.0).normalize(),
            mass: 1.2,
            com: Vector3::new(0.05, 0.0, 0.2),
            inertia: inertia(0.04, 0.05, 0.02, -0.003),
        },
    ];
    SpatialChain::new(bodies, [0.5, -0.3, -9.81], [0.0, 0.0, 0.4])
}

fn max_abs(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).amax()
}

#[test]
fn planar_chain_as_spatial_gives_the_closed_forms() {
    for (links, gravity) in
        [(vec![Link { mass: 1.0, length: 2.0, com: 1.0, inertia: 1.0 }; 2], [0.0, 0.0]), (three_links(), [0.3, -9.81])]
    {
        let planar = PlanarChain::new(links.clone(), gravity);
        let spatial = planar_as_spatial(&links, gravity);
        let n = links.len();
        let mut ws_p = planar.workspace();
        let mut ws_s = spatial.workspace();
        for pair in points(n, 20, 1).chunks(2) {
            let q = &pair[0] * 3.0;
            let qd = &pair[1];
            let tol = 1e-12;
            assert!(max_abs(&planar.mass_matrix(&q), &spatial.mass_matrix(&q)) < tol);
            for (a, b) in planar.mass_matrix_derivatives(&q).iter().zip(spatial.mass_matrix_derivatives(&q)) {
                assert!(max_abs(a, &b) < tol);
            }
            for (a, b) in planar.christoffel(&q).iter().zip(spatial.christoffel(&q)) {
                assert!(max_abs(a, &b) < tol);
            }
            assert!((planar.coriolis(&q, qd) - spatial.coriolis(&q, qd)).amax() < tol);
            let qs = q.as_slice();
            assert!((planar.gravity_potential(qs) - spatial.gravity_potential(qs)).abs() < tol * 10.0);
            assert!((planar.gravity_gradient(qs) - spatial.gravity_gradient(qs)).amax() < tol * 10.0);
            assert!(max_abs(&planar.gravity_hessian(qs), &spatial.gravity_hessian(qs)) < tol * 10.0);
            // Geodesic and Jacobi-field right-hand sides.
            let mut y: Vec<f64> = q.iter().chain(qd.iter()).copied().collect();
            y.extend((0..2 * n * n).map(|i| ((i * 7 % 11) as f64 - 5.0) / 5.0));
            let (mut dp, mut ds) = (vec![0.0; y.len()], vec![0.0; y.len()]);
            assert!(planar.variational_rhs(&mut ws_p, &y, &mut dp));
            assert!(spatial.variational_rhs(&mut ws_s, &y, &mut ds));
            let err = dp.iter().zip(&ds).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(err < 1e-11, "variational rhs differs by {err}");
            // Drawing: the planar chain's own plane (the spatial list starts with the base
            // origin, here also the first joint's).
            for (a, b) in planar.joint_positions(qs).iter().zip(&spatial.joint_positions(qs)[1..]) {
                if gravity == [0.0, 0.0] {
                    assert!((a[0] - b[0]).abs() < tol && (a[1] - b[1]).abs() < tol);
                }
            }
        }
    }
}

#[test]
fn crba_equals_rnea_columns_and_is_spd() {
    let chain = skew_arm();
    let n = chain.dof();
    for q in points(n, 20, 2) {
        let q = q * 3.0;
        let m = chain.mass_matrix(&q);
        for j in 0..n {
            let e: Vec<f64> = (0..n).map(|k| if k == j { 1.0 } else { 0.0 }).collect();
            let col = chain.inverse_dynamics(q.as_slice(), &vec![0.0; n], &e, false);
            assert!((m.column(j) - col).amax() < 1e-13);
        }
        assert!((&m - m.transpose()).amax() < 1e-15);
        assert!(m.symmetric_eigen().eigenvalues.min() > 0.0);
    }
}

#[test]
fn derivatives_match_finite_differences() {
    let chain = skew_arm();
    let n = chain.dof();
    let h = 1e-6;
    for q in points(n, 10, 3) {
        let shifted = |p: usize, s: f64| {
            let mut x = q.clone();
            x[p] += s * h;
            x
        };
        let dm = chain.mass_matrix_derivatives(&q);
        let fd: Vec<DMatrix<f64>> = (0..n)
            .map(|p| (chain.mass_matrix(&shifted(p, 1.0)) - chain.mass_matrix(&shifted(p, -1.0))) / (2.0 * h))
            .collect();
        for p in 0..n {
            assert!(max_abs(&dm[p], &fd[p]) < 1e-8, "dM/dq{p}");
        }
        let gamma = chain.christoffel(&q);
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let textbook = 0.5 * (fd[k][(i, j)] + fd[j][(i, k)] - fd[i][(j, k)]);
                    assert!((gamma[i][(j, k)] - textbook).abs() < 1e-8);
                }
            }
        }
        // Gravity: potential → gradient → Hessian.
        let g = chain.gravity_gradient(q.as_slice());
        let hess = chain.gravity_hessian(q.as_slice());
        for p in 0..n {
            let (qp, qm) = (shifted(p, 1.0), shifted(p, -1.0));
            let fd_u = (chain.gravity_potential(qp.as_slice()) - chain.gravity_potential(qm.as_slice())) / (2.0 * h);
            assert!((g[p] - fd_u).abs() < 1e-7);
            let fd_g = (chain.gravity_gradient(qp.as_slice()) - chain.gravity_gradient(qm.as_slice())) / (2.0 * h);
            assert!((hess.column(p) - fd_g).amax() < 1e-7);
        }
    }
}

#[test]
fn variational_rhs_matches_finite_differences_of_geodesic_rhs() {
    let chain = skew_arm();
    let n = chain.dof();
    let mut ws = chain.workspace();
    for pair in points(n, 8, 4).chunks(2) {
        let (q, qd) = (&pair[0], &pair[1]);
        let phi: Vec<f64> = (0..2 * n * n).map(|i| ((i * 7 % 11) as f64 - 5.0) / 5.0).collect();
        let mut y: Vec<f64> = q.iter().chain(qd.iter()).copied().collect();
        y.extend_from_slice(&phi);
        let mut dy = vec![0.0; y.len()];
        assert!(chain.variational_rhs(&mut ws, &y, &mut dy));
        // The Coriolis term is the Christoffel contraction.
        let gamma = chain.christoffel(q);
        let h_vec = chain.coriolis(q, qd);
        for i in 0..n {
            assert!((h_vec[i] - qd.dot(&(&gamma[i] * qd))).abs() < 1e-12);
        }
        let h = 1e-6;
        for col in 0..n {
            let shifted = |sign: f64| {
                let mut ys = vec![0.0; 2 * n];
                for r in 0..n {
                    ys[r] = q[r] + sign * h * phi[r + n * col];
                    ys[n + r] = qd[r] + sign * h * phi[n * n + r + n * col];
                }
                let mut d = vec![0.0; 2 * n];
                assert!(chain.geodesic_rhs(&mut chain.workspace(), &ys, &mut d));
                d
            };
            let (dp, dm) = (shifted(1.0), shifted(-1.0));
            for r in 0..n {
                let fd = (dp[n + r] - dm[n + r]) / (2.0 * h);
                let an = dy[2 * n + n * n + r + n * col];
                assert!((fd - an).abs() < 1e-6, "row {r} col {col}: {fd} vs {an}");
            }
        }
    }
}

/// Free motion under gravity (no springs, no damping) keeps E = ½q̇ᵀMq̇ + U_g: RK4 with a small
/// step on M q̈ + h = −∇U_g.
#[test]
fn energy_is_conserved_in_free_motion_under_gravity() {
    let chain = skew_arm();
    let n = chain.dof();
    let mut ws = chain.workspace();
    let mut rhs = |y: &[f64]| {
        let (q, qd) = y.split_at(n);
        let tau: Vec<f64> = chain.gravity_gradient(q).iter().map(|g| -g).collect();
        let mut qdd = vec![0.0; n];
        assert!(chain.acceleration(&mut ws, q, qd, &tau, &mut qdd));
        qd.iter().chain(&qdd).copied().collect::<Vec<f64>>()
    };
    let energy = |y: &[f64]| {
        let q = DVector::from_column_slice(&y[..n]);
        let qd = DVector::from_column_slice(&y[n..]);
        0.5 * qd.dot(&(chain.mass_matrix(&q) * &qd)) + chain.gravity_potential(&y[..n])
    };
    let mut y = vec![0.3, -0.8, 1.1, 0.5, 0.0, -0.7];
    let e0 = energy(&y);
    let dt = 1e-3;
    let mut swing: f64 = 0.0;
    for _ in 0..3000 {
        let k1 = rhs(&y);
        let y2: Vec<f64> = y.iter().zip(&k1).map(|(a, k)| a + 0.5 * dt * k).collect();
        let k2 = rhs(&y2);
        let y3: Vec<f64> = y.iter().zip(&k2).map(|(a, k)| a + 0.5 * dt * k).collect();
        let k3 = rhs(&y3);
        let y4: Vec<f64> = y.iter().zip(&k3).map(|(a, k)| a + dt * k).collect();
        let k4 = rhs(&y4);
        for i in 0..2 * n {
            y[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        swing = swing.max((chain.gravity_potential(&y[..n]) - chain.gravity_potential(&[0.3, -0.8, 1.1])).abs());
    }
    // The arm really swings (tens of J exchanged) while E stays put.
    assert!(swing > 5.0, "swing {swing}");
    assert!((energy(&y) - e0).abs() < 1e-8 * swing, "energy drift {}", energy(&y) - e0);
}

/// A one-link pendulum carrying a point mass at a known radius has the analytic inertia
/// I + m c² + m_p x² about its joint and the analytic gravity load (m c + m_p x) g, planar and
/// spatial alike.
#[test]
fn point_mass_on_one_link_matches_the_analytic_inertia() {
    let link = Link { mass: 1.0, length: 1.0, com: 0.5, inertia: 1.0 / 12.0 };
    let (mp, x) = (0.3, 0.8);
    let added = [crate::model::PointMass { link: 0, position: [x, 0.0, 0.0], mass: mp }];
    let expected = 1.0 / 12.0 + 1.0 * 0.25 + mp * x * x;
    let planar = crate::model::Chain::new(vec![link], [0.0, -9.81]).with_point_masses(&added);
    let spatial = crate::model::Chain::Spatial(planar_as_spatial(&[link], [0.0, -9.81])).with_point_masses(&added);
    for chain in [&planar, &spatial] {
        for q in [0.0, 0.7, -2.1] {
            let m = chain.mass_matrix(&DVector::from_vec(vec![q]));
            assert!((m[(0, 0)] - expected).abs() < 1e-12, "M = {} against {expected}", m[(0, 0)]);
            let g = chain.gravity_gradient(&[q]);
            let load = (1.0 * 0.5 + mp * x) * 9.81 * q.cos();
            assert!((g[0] - load).abs() < 1e-12, "∂U/∂q = {} against {load}", g[0]);
        }
    }
}

/// Point masses on a three-link chain give the same M(q), ∂M/∂q and gravity whether the chain is
/// planar or spatial, and masses on joint mounts sit where the next joint is.
#[test]
fn point_masses_agree_planar_and_spatial() {
    let links = [
        Link { mass: 2.0, length: 0.6, com: 0.3, inertia: 0.06 },
        Link { mass: 1.5, length: 0.5, com: 0.2, inertia: 0.03 },
        Link { mass: 0.8, length: 0.4, com: 0.25, inertia: 0.01 },
    ];
    let planar = crate::model::Chain::new(links.to_vec(), [0.0, -9.81]);
    let spatial = crate::model::Chain::Spatial(planar_as_spatial(&links, [0.0, -9.81]));
    assert_eq!(planar.joint_mount(0), None);
    assert_eq!(planar.joint_mount(2), Some((1, [0.5, 0.0, 0.0])));
    assert_eq!(spatial.joint_mount(2), planar.joint_mount(2));
    assert_eq!(spatial.link_end(2), planar.link_end(2));
    let added = [
        crate::model::PointMass { link: 0, position: [0.6, 0.0, 0.0], mass: 0.4 },
        crate::model::PointMass { link: 1, position: [0.25, 0.0, 0.0], mass: 0.05 },
        crate::model::PointMass { link: 1, position: [0.5, 0.0, 0.0], mass: 0.2 },
    ];
    let (planar, spatial) = (planar.with_point_masses(&added), spatial.with_point_masses(&added));
    for q in points(3, 20, 7) {
        let (a, b) = (planar.mass_matrix(&q), spatial.mass_matrix(&q));
        assert!((a - b).norm() < 1e-12);
        let (a, b) = (planar.mass_matrix_derivatives(&q), spatial.mass_matrix_derivatives(&q));
        assert!(a.iter().zip(&b).all(|(a, b)| (a - b).norm() < 1e-12));
        let (a, b) = (planar.gravity_gradient(q.as_slice()), spatial.gravity_gradient(q.as_slice()));
        assert!((a - b).norm() < 1e-12);
    }
}
