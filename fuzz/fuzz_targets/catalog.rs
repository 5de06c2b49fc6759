//! Catalogues: any text either loads for a two- and a three-joint robot and expands into
//! candidates, or is an `Error` naming the file. Never a panic.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use springfit::elements::catalog::Catalog;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = Path::new("catalogs/fuzz.toml");
    for dof in [2, 3] {
        match Catalog::parse(path, text, dof) {
            Ok(catalog) => {
                assert!(!catalog.families.is_empty());
                let q_eq = vec![0.0; dof];
                let candidates = catalog.expand(&q_eq, |_| (-1.0, 1.0));
                assert!(!candidates.is_empty(), "a valid catalogue expands into no candidate");
                for c in &candidates {
                    assert_eq!(c.element.coupling.len(), dof);
                    assert!(c.element.offset.is_finite(), "non-finite offset {:?}", c.element);
                    assert!(c.family < catalog.families.len());
                }
            }
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains("catalogs/fuzz.toml"), "error does not name the file: {msg}");
            }
        }
    }
});
