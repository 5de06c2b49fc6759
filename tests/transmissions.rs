//! Transmissions in `parts.csv`: each element's coupling made by a joint, a bevel-gear
//! differential or a tendon with its pulley radii, and a coupling no transmission makes left
//! without a part, the `[parts]` limit named (`realise::transmission`, docs/parts.md,
//! "Transmissions").

mod util;

use util::{design_variant, springfit, temp_dir, write};

/// A bill on the default arm with one element of each transmission and one beyond the pulley
/// limits: `springfit parts` gives the first four their transmission and radii, and the fifth no
/// part, its limit naming `[parts] min_pulley_radius_mm` (exit 1, as for any element without a
/// part).
#[test]
fn parts_name_each_transmission_and_refuse_a_coupling_beyond_the_pulleys() {
    let dir = temp_dir("transmissions");
    // The springs alone do not hold q_eq against gravity: the design lets such a bill through.
    let design = design_variant(
        &dir,
        "double_pendulum",
        &[
            ("equilibrium.bill_tolerance", toml::Value::Float(1e3)),
            ("fit.evaluation_directions", toml::Value::Integer(12)),
            ("fit.evaluation_samples", toml::Value::Integer(10)),
        ],
    );
    let rows = "J1,joint,linear,,1;0,0.3,5,N*m/rad,0,0,,0,,,,,,\n\
B1,bevel,linear,,1;-2,0.1,5,N*m/rad,0,0,,0,,,,,,\n\
T1,tendon,linear,,1;0.7,0.2,5,N*m/rad,0,0,,0,,,,,,\n\
T2,tendon,compression,+,0.3;-1,0,5,N*m/rad,0,0,,0,,,,,,\n\
N1,beyond,linear,,1;0.1,0.2,5,N*m/rad,0,0,,0,,,,,,\n";
    write(&dir, "bom.csv", &format!("{}\n{rows}", springfit::files::bom::HEADER));
    springfit(&dir, &["parts", design.to_str().unwrap(), "--bom", "bom.csv", "--out", "parts"])
        .fails(1, &["N1", "min_pulley_radius_mm"]);
    let csv = std::fs::read_to_string(dir.join("parts/parts.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap_or_else(|| panic!("parts.csv lacks {n}"));
    let rows: Vec<Vec<String>> = csv.lines().skip(1).map(|l| springfit::files::split_csv_line(l).unwrap()).collect();
    let row = |id: &str| rows.iter().find(|r| r[0] == id).unwrap_or_else(|| panic!("{id}: {csv}"));
    let at = |id: &str, c: &str| row(id)[col(c)].clone();
    assert_eq!((at("J1", "transmission"), at("J1", "pulley_radii_mm")), ("joint".into(), String::new()));
    assert_eq!((at("B1", "transmission"), at("B1", "pulley_radii_mm")), ("bevel differential".into(), String::new()));
    // ρ = 40 mm at the default limits (10–40 mm): the radii in proportion to the coupling,
    // signed by the side the cable crosses.
    assert_eq!((at("T1", "transmission"), at("T2", "transmission")), ("tendon".into(), "tendon".into()));
    let radii = |id: &str| -> Vec<f64> { at(id, "pulley_radii_mm").split(';').map(|r| r.parse().unwrap()).collect() };
    let near = |a: &[f64], b: &[f64]| a.len() == b.len() && a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-12);
    assert!(near(&radii("T1"), &[40.0, 28.0]), "{:?}", radii("T1"));
    assert!(near(&radii("T2"), &[12.0, -40.0]), "{:?}", radii("T2"));
    // A linear spring's torque changes sign over the region: an antagonistic pair, preloaded. A
    // compression spring's torque k·max(0, x − x₀) never does: one cable.
    assert!(at("T1", "geometry").contains("antagonistic pair"), "{}", at("T1", "geometry"));
    assert!(at("T2", "geometry").contains("one cable"), "{}", at("T2", "geometry"));
    assert!(!at("T1", "mechanism").is_empty() && at("T1", "limit").is_empty());
    // 1 : 0.1 needs a 4 mm pulley beside a 40 mm one: no transmission, so no part.
    assert_eq!(at("N1", "transmission"), "");
    assert!(at("N1", "mechanism").is_empty());
    let limit = at("N1", "limit");
    assert!(limit.contains("`[parts] min_pulley_radius_mm` = 10 mm") && limit.contains("4.000 mm"), "{limit}");
}

/// A coupling a tendon family generated carries its pulleys: `springfit parts` reports exactly the
/// radii the catalogue stocks (10 mm and 30 mm), not the chooser's rescaling of the same coupling
/// (13.33 mm and 40 mm), and a design whose `[parts]` does not allow a stocked pulley is refused
/// naming the catalogue's field and the `[parts]` key.
#[test]
fn a_tendon_familys_coupling_is_built_over_exactly_its_pulleys() {
    let dir = temp_dir("tendon_family");
    let design = design_variant(
        &dir,
        "double_pendulum",
        &[
            ("fit.trimmed_weight", toml::Value::Float(0.0)),
            ("equilibrium.bill_tolerance", toml::Value::Float(1e3)),
            ("fit.evaluation_directions", toml::Value::Integer(12)),
            ("fit.evaluation_samples", toml::Value::Integer(10)),
        ],
    );
    write(
        &dir,
        "tendons.toml",
        "[[family]]\nname = \"t\"\nprofile = \"linear\"\noffsets = \"equilibrium\"\n\
         couplings = { tendons = { radii_mm = [10, 30], max_crossed = 2 } }\n",
    );
    let mut table: toml::Table = toml::from_str(&std::fs::read_to_string(&design).unwrap()).unwrap();
    table.insert("catalog".into(), toml::Value::String("tendons.toml".into()));
    std::fs::write(&design, toml::to_string(&table).unwrap()).unwrap();
    // (10, 30) and (10, −30): the couplings (1/3, ±1) as the bill writes them.
    let third = 1.0_f64 / 3.0;
    let rows = format!(
        "T1,t,linear,,{third};1,0.2,5,N*m/rad,0,0,,0,,,,,,\nT2,t,linear,,{third};-1,0.2,5,N*m/rad,0,0,,0,,,,,,\n"
    );
    write(&dir, "bom.csv", &format!("{}\n{rows}", springfit::files::bom::HEADER));
    springfit(&dir, &["parts", design.to_str().unwrap(), "--bom", "bom.csv", "--out", "parts"]).ok();
    let csv = std::fs::read_to_string(dir.join("parts/parts.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let rows: Vec<Vec<String>> = csv.lines().skip(1).map(|l| springfit::files::split_csv_line(l).unwrap()).collect();
    let at = |id: &str, c: &str| rows.iter().find(|r| r[0] == id).unwrap()[col(c)].clone();
    assert_eq!((at("T1", "transmission"), at("T1", "pulley_radii_mm")), ("tendon".into(), "10;30".into()));
    assert_eq!((at("T2", "transmission"), at("T2", "pulley_radii_mm")), ("tendon".into(), "10;-30".into()));
    // A design allowing pulleys of 12 mm and up: the stocked 10 mm one is refused.
    let parts = table.get_mut("parts").and_then(|p| p.as_table_mut()).unwrap();
    parts.insert("min_pulley_radius_mm".into(), toml::Value::Float(12.0));
    std::fs::write(&design, toml::to_string(&table).unwrap()).unwrap();
    springfit(&dir, &["check", design.to_str().unwrap()])
        .fails(2, &["family[0].couplings.tendons.radii_mm[0]", "`[parts] min_pulley_radius_mm` = 12 mm"]);
}
