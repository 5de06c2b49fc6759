//! Design files: any text either loads into a design whose mass matrix can be evaluated, or is an
//! `Error` naming the file. Never a panic.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use springfit::design::Design;
use springfit::geodesic::Region;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = Path::new("designs/fuzz.toml");
    match Design::parse(path, text) {
        Ok(design) => {
            let n = design.dof();
            assert!((1..=8).contains(&n));
            assert_eq!(design.q_eq.len(), n);
            assert!(design.q_eq.iter().all(|q| q.is_finite()), "non-finite equilibrium {:?}", design.q_eq);
            let m = design.chain.mass_matrix(&design.q_eq);
            assert_eq!(m.shape(), (n, n));
            assert!(m.iter().all(|x| x.is_finite()), "non-finite mass matrix {m}");
            assert!(m.clone().cholesky().is_some(), "mass matrix at the equilibrium is not positive definite: {m}");
            let q = design.q_eq.as_slice();
            let u = design.chain.gravity_potential(q);
            let g = design.chain.gravity_gradient(q);
            let h = design.chain.gravity_hessian(q);
            assert!(u.is_finite() && g.iter().chain(h.iter()).all(|x| x.is_finite()), "gravity {u} {g} {h}");
            let _ = design.chain.christoffel(&design.q_eq);
            let _ = design.chain.joint_positions(q);
            match &design.region {
                Region::Ball { radius } => assert!(radius.is_finite() && *radius > 0.0),
                Region::Box { lower, upper } | Region::Clipped { lower, upper, .. } => {
                    assert_eq!((lower.len(), upper.len()), (n, n));
                    for i in 0..n {
                        assert!(lower[i] < design.q_eq[i] && design.q_eq[i] < upper[i]);
                    }
                }
            }
            assert!(!design.name.is_empty());
            let _ = (&design.description, &design.catalog, &design.scenarios);
            let _ = format!("{:?}", design.fit);
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("designs/fuzz.toml"), "error does not name the file: {msg}");
        }
    }
});
