//! Bills of materials: any text either parses into rows whose spring set can be evaluated, or is
//! an `Error` naming the file. Never a panic.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use springfit::files::bom;
use springfit::potential::Potential;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = Path::new("out/fuzz/bom.csv");
    match bom::parse(path, text) {
        Ok(rows) => {
            assert!(!rows.is_empty());
            let set = springfit::fit::bill::spring_set(&rows);
            let n = set.dof();
            assert!(n >= 1);
            for q in [vec![0.0; n], vec![0.5; n], (0..n).map(|i| (i as f64 - 1.0) * 1.3).collect()] {
                let g = set.gradient(&q).unwrap();
                let h = set.hessian(&q).unwrap();
                let _ = set.value(&q).unwrap();
                assert_eq!(g.len(), n);
                assert_eq!(h.shape(), (n, n));
            }
            // Writing the rows back and reading them again gives the same rows (cams are written
            // as rows naming files, which are not on disk here: only written).
            let files = bom::files("bom.csv", &rows);
            if files.len() == 1 {
                let again = bom::parse(path, &files[0].1).expect("a written bill of materials reads back");
                assert_eq!(again, rows);
            }
            let _ = bom::to_markdown("fuzz", &rows);
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("out/fuzz/bom.csv"), "error does not name the file: {msg}");
        }
    }
});
