//! Settings of the parts: the design's `[parts]` section (what every spring is made of, how well,
//! for how long, and the room it has).

use serde::{Deserialize, Serialize};

/// The wire materials `material` may name: the keys of the material table in
/// `realise::material` (a test there keeps the two lists equal).
pub const MATERIALS: &[&str] =
    &["EN10270-1-SM", "EN10270-1-DM", "ASTM-A228", "ASTM-A313-302", "ASTM-A229", "ASTM-A232", "ASTM-A401"];

/// Fewest swings for which the default wire is a dynamic grade: below it (a spring loaded a few
/// thousand times) EN 10270-1's static grade SM is enough.
pub const DYNAMIC_FROM_CYCLES: f64 = 1e4;

/// What `[parts] stop_mechanism` may name: the lightest mechanism that passes (the default), or
/// one forced.
pub const STOP_MECHANISMS: &[&str] = &["lightest", "torsion", "drum"];

/// What `[parts] trim_mechanism` may name: the lightest mechanism that passes (the default), or
/// one forced.
pub const TRIM_MECHANISMS: &[&str] = &["lightest", "leaf", "crank"];

/// `[parts] material`: one wire key, or the list of wires the maker stocks (each spring is then
/// wound from the lightest listed wire that passes every check; `realise::mechanism::Wires`).
/// A string and a one-item list wind the same springs; the string stays a string when written.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum MaterialSetting {
    /// One wire for every spring.
    One(String),
    /// The wires a maker stocks, in its order (which breaks ties between equally light springs).
    List(Vec<String>),
}

impl MaterialSetting {
    /// The keys, in the order given.
    pub fn keys(&self) -> Vec<&str> {
        match self {
            MaterialSetting::One(k) => vec![k.as_str()],
            MaterialSetting::List(l) => l.iter().map(String::as_str).collect(),
        }
    }
}

impl From<&str> for MaterialSetting {
    fn from(key: &str) -> Self {
        MaterialSetting::One(key.into())
    }
}

/// By hand rather than `untagged`, so that a value of the wrong kind is refused naming what the
/// key takes instead of "did not match any variant".
impl<'de> Deserialize<'de> for MaterialSetting {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = MaterialSetting;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "a wire key or a list of wire keys ({})", MATERIALS.join(", "))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<MaterialSetting, E> {
                Ok(MaterialSetting::One(v.into()))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<MaterialSetting, A::Error> {
                let mut list = Vec::new();
                while let Some(k) = seq.next_element::<String>()? {
                    list.push(k);
                }
                Ok(MaterialSetting::List(list))
            }
        }
        d.deserialize_any(Visit)
    }
}

/// `[[parts.element]]`: the room one element has, overriding the defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElementEnvelope {
    /// The element's id in the bill of materials (`S03`, `C01`).
    pub id: String,
    /// Largest outer diameter (or leaf width), mm.
    pub max_outer_diameter_mm: Option<f64>,
    /// Largest length, mm.
    pub max_length_mm: Option<f64>,
    /// Largest lever or crank radius, mm.
    pub max_lever_mm: Option<f64>,
}

/// `[parts]`: how the fitted elements become springs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PartsSettings {
    /// Wire material, a key of the material table ([`MATERIALS`]) or a list of them (the wires
    /// the maker stocks); unset, it follows `cycles` ([`PartsSettings::material_keys`]).
    pub material: Option<MaterialSetting>,
    /// Shot-peened springs (a higher endurance: Zimmerli's peened point, Table 10-10's peened row).
    pub shot_peened: bool,
    /// EN 15800 quality grade 1, 2 or 3 (1 the tightest): each spring's rate tolerance.
    pub grade: u8,
    /// Swings every spring must survive (Goodman, at the amplitude of the design's scenarios).
    pub cycles: f64,
    /// Factor on every stress limit, static and fatigue (≥ 1).
    pub safety_factor: f64,
    /// Largest outer diameter of a spring (or width of a leaf), mm.
    pub max_outer_diameter_mm: f64,
    /// Largest length of a spring (a torsion spring's body, a crank's spring and cable run, a
    /// leaf's clamp travel, a follower's free length), mm.
    pub max_length_mm: f64,
    /// Largest crank radius or lever, mm.
    pub max_lever_mm: f64,
    /// Shaft a torsion spring sits on, mm (its arbor must clear it when wound).
    pub shaft_diameter_mm: f64,
    /// Radius of the rollers a crank's cable runs over, mm (0: an ideal eyelet).
    pub pulley_radius_mm: f64,
    /// Smallest pulley radius of a tendon (a cable over a pulley at each joint it crosses), mm.
    pub min_pulley_radius_mm: f64,
    /// Largest pulley radius of a tendon, mm: a tendon's radii are in proportion to its coupling
    /// with the largest at this one (`realise::transmission`).
    pub max_pulley_radius_mm: f64,
    /// Most joints one tendon crosses.
    pub max_joints_crossed: usize,
    /// A stock list (CSV, relative to the design file) to order parts from before winding any;
    /// unset, the list springfit ships (`files::stock::SHIPPED`) when `prefer_stock` is on.
    pub stock: Option<String>,
    /// Order a listed spring whenever one passes every check (a crank is then built round it);
    /// false: wind every crank spring (a named list's torsion and compression springs are still
    /// ordered where their rate matches the wound one's) and read no list unless `stock` names one.
    pub prefer_stock: bool,
    /// The mechanism of a one-sided compression element: `lightest` (the lighter of the two that
    /// passes every check), `torsion` (a torsion spring on a leg stop) or `drum` (a compression
    /// spring pulled by a cable wound on a drum on x).
    pub stop_mechanism: String,
    /// The mechanism of a trim: `lightest` (the lighter of the two that passes), `leaf` (a leaf
    /// spring in a sliding clamp) or `crank` (an extension spring on a geared crank whose pin
    /// radius, set by a screw, sets the rate).
    pub trim_mechanism: String,
    /// Per-element envelopes.
    pub element: Vec<ElementEnvelope>,
}

impl Default for PartsSettings {
    fn default() -> Self {
        PartsSettings {
            material: None,
            shot_peened: false,
            grade: 2,
            cycles: 1e6,
            safety_factor: 1.1,
            max_outer_diameter_mm: 150.0,
            max_length_mm: 400.0,
            max_lever_mm: 100.0,
            shaft_diameter_mm: 12.0,
            pulley_radius_mm: 5.0,
            // 10 mm: a pulley of 20 mm diameter is 25 times the 0.8 mm cable that carries up to
            // about 100 N at a safety factor of 5 (a cable bent round a pulley much smaller than
            // 20–40 of its diameters wears out), and the 14–19 mm pulleys of built biarticular
            // arms sit between the two limits.
            min_pulley_radius_mm: 10.0,
            // 40 mm: an 80 mm pulley fits inside the joint housing of a UR5-sized arm (about
            // 90 mm across); the limits allow radii 1 : 4 on one tendon.
            max_pulley_radius_mm: 40.0,
            // 5: the longest run of joints the shipped catalogues turn together (the five-link
            // pendulum's runs, one cable on equal pulleys); each joint crossed adds pulleys whose
            // friction and the cable's stretch the realised design does not model yet.
            max_joints_crossed: 5,
            stock: None,
            prefer_stock: true,
            stop_mechanism: "lightest".into(),
            trim_mechanism: "lightest".into(),
            element: Vec::new(),
        }
    }
}

impl PartsSettings {
    /// The wires springs are wound from, each spring from the lightest of them that passes every
    /// check (ties: this order): `material` when set, else EN 10270-1's dynamic grade DM for
    /// [`DYNAMIC_FROM_CYCLES`] swings or more and the static grade SM below. DM alone by default
    /// and not with the stronger chrome-silicon or chrome-vanadium wire: whether a maker stocks
    /// those is the design's to say, and they are not drawn below 1.6 and 0.8 mm, which most crank
    /// springs of the triple pendulum are (docs/parts.md, Materials, has the measurements).
    pub fn material_keys(&self) -> Vec<&str> {
        match &self.material {
            Some(m) => m.keys(),
            None if self.cycles >= DYNAMIC_FROM_CYCLES => vec!["EN10270-1-DM"],
            None => vec!["EN10270-1-SM"],
        }
    }

    /// The wires of [`PartsSettings::material_keys`] as printed: the key, or the keys joined by
    /// `, `.
    pub fn material_key(&self) -> String {
        self.material_keys().join(", ")
    }

    /// Why the wire is what it is, in words (printed with the parts).
    pub fn material_choice(&self) -> String {
        let static_grade = self.cycles >= DYNAMIC_FROM_CYCLES && self.material_keys().contains(&"EN10270-1-SM");
        match &self.material {
            Some(MaterialSetting::List(l)) if l.len() > 1 => {
                let rule = "set in [parts] material: each spring wound from the lightest listed wire that passes every check, the earlier listed on a tie";
                if static_grade {
                    format!(
                        "{rule}; EN10270-1-SM a static grade for {} swings: EN 10270-1 DM is the dynamic grade",
                        self.cycles
                    )
                } else {
                    rule.into()
                }
            }
            Some(_) if static_grade => format!(
                "set in [parts] material; a static grade for {} swings: EN 10270-1 DM is the dynamic grade",
                self.cycles
            ),
            Some(_) => "set in [parts] material".into(),
            None if self.cycles >= DYNAMIC_FROM_CYCLES => {
                format!("the default for {} swings: a dynamic grade from {DYNAMIC_FROM_CYCLES} swings", self.cycles)
            }
            None => format!("the default for {} swings: the static grade below {DYNAMIC_FROM_CYCLES}", self.cycles),
        }
    }

    /// Checks the settings, naming the bad field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let err = |f: &str, r: String| Err((format!("parts.{f}"), r));
        match &self.material {
            Some(MaterialSetting::One(k)) if !MATERIALS.contains(&k.as_str()) => {
                return err("material", format!("unknown material `{k}`: expected one of {}", MATERIALS.join(", ")));
            }
            Some(MaterialSetting::List(l)) if l.is_empty() => {
                return err(
                    "material",
                    format!("an empty list of wires: name at least one of {}", MATERIALS.join(", ")),
                );
            }
            Some(MaterialSetting::List(l)) => {
                for (i, k) in l.iter().enumerate() {
                    if !MATERIALS.contains(&k.as_str()) {
                        return err(
                            &format!("material[{i}]"),
                            format!("unknown material `{k}`: expected one of {}", MATERIALS.join(", ")),
                        );
                    }
                    if let Some(j) = l[..i].iter().position(|e| e == k) {
                        return err(&format!("material[{i}]"), format!("`{k}` is listed twice (also item {j})"));
                    }
                }
            }
            _ => {}
        }
        if !(1..=3).contains(&self.grade) {
            return err("grade", format!("must be the EN 15800 quality grade 1, 2 or 3, got {}", self.grade));
        }
        if !(self.cycles.is_finite() && (1.0..=1e9).contains(&self.cycles)) {
            return err("cycles", format!("must be a number of swings from 1 to 10⁹, got {}", self.cycles));
        }
        if !(self.safety_factor.is_finite() && (1.0..=10.0).contains(&self.safety_factor)) {
            return err("safety_factor", format!("must be from 1 to 10, got {}", self.safety_factor));
        }
        let positive = |v: f64| v.is_finite() && v > 0.0 && v <= 10_000.0;
        for (f, v) in [
            ("max_outer_diameter_mm", self.max_outer_diameter_mm),
            ("max_length_mm", self.max_length_mm),
            ("max_lever_mm", self.max_lever_mm),
            ("shaft_diameter_mm", self.shaft_diameter_mm),
        ] {
            if !positive(v) {
                return err(f, format!("must be a positive size in mm up to 10000, got {v}"));
            }
        }
        if !(self.pulley_radius_mm.is_finite() && (0.0..=1000.0).contains(&self.pulley_radius_mm)) {
            return err("pulley_radius_mm", format!("must be from 0 to 1000 mm, got {}", self.pulley_radius_mm));
        }
        for (f, v) in
            [("min_pulley_radius_mm", self.min_pulley_radius_mm), ("max_pulley_radius_mm", self.max_pulley_radius_mm)]
        {
            if !(v.is_finite() && v > 0.0 && v <= 1000.0) {
                return err(f, format!("must be a radius above 0 and up to 1000 mm, got {v}"));
            }
        }
        if self.min_pulley_radius_mm > self.max_pulley_radius_mm {
            return err(
                "min_pulley_radius_mm",
                format!(
                    "{} mm is above max_pulley_radius_mm = {} mm",
                    self.min_pulley_radius_mm, self.max_pulley_radius_mm
                ),
            );
        }
        if !(2..=crate::limits::MAX_LINKS).contains(&self.max_joints_crossed) {
            return err(
                "max_joints_crossed",
                format!("must be from 2 to {}, got {}", crate::limits::MAX_LINKS, self.max_joints_crossed),
            );
        }
        for (f, v, allowed) in [
            ("stop_mechanism", &self.stop_mechanism, STOP_MECHANISMS),
            ("trim_mechanism", &self.trim_mechanism, TRIM_MECHANISMS),
        ] {
            if !allowed.contains(&v.as_str()) {
                return err(f, format!("unknown mechanism `{v}`: expected one of {}", allowed.join(", ")));
            }
        }
        for (i, e) in self.element.iter().enumerate() {
            for (f, v) in [
                ("max_outer_diameter_mm", e.max_outer_diameter_mm),
                ("max_length_mm", e.max_length_mm),
                ("max_lever_mm", e.max_lever_mm),
            ] {
                if let Some(v) = v
                    && !positive(v)
                {
                    return err(&format!("element[{i}].{f}"), format!("must be a positive size in mm, got {v}"));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A string and a list both read, a string is written back as a string, and a value of
    /// another kind is refused naming what the key takes.
    #[test]
    fn material_is_a_key_or_a_list() {
        let read = |t: &str| toml::from_str::<PartsSettings>(t);
        let one = read("material = \"ASTM-A401\"").unwrap();
        assert_eq!(one.material, Some(MaterialSetting::One("ASTM-A401".into())));
        assert_eq!(one.material_keys(), ["ASTM-A401"]);
        assert!(toml::to_string(&one).unwrap().contains("material = \"ASTM-A401\""));
        let list = read("material = [\"EN10270-1-DM\", \"ASTM-A401\"]").unwrap();
        assert_eq!(list.material_keys(), ["EN10270-1-DM", "ASTM-A401"]);
        assert_eq!(list.material_key(), "EN10270-1-DM, ASTM-A401");
        assert!(list.material_choice().contains("lightest listed wire"), "{}", list.material_choice());
        assert_eq!(PartsSettings { cycles: 1e3, ..Default::default() }.material_keys(), ["EN10270-1-SM"]);
        let bad = read("material = 3").unwrap_err().to_string();
        assert!(bad.contains("a wire key or a list of wire keys"), "{bad}");
    }

    #[test]
    fn bad_settings_name_their_field() {
        assert!(PartsSettings::default().validate().is_ok());
        let bad = |s: PartsSettings, field: &str, words: &str| {
            let (f, r) = s.validate().unwrap_err();
            assert_eq!(f, field);
            assert!(r.contains(words), "{r}");
        };
        bad(
            PartsSettings { material: Some("unobtainium".into()), ..Default::default() },
            "parts.material",
            "EN10270-1-SM",
        );
        let list = |keys: &[&str]| PartsSettings {
            material: Some(MaterialSetting::List(keys.iter().map(|k| k.to_string()).collect())),
            ..Default::default()
        };
        assert!(list(&["EN10270-1-DM", "ASTM-A401"]).validate().is_ok());
        bad(list(&[]), "parts.material", "empty list");
        bad(list(&["EN10270-1-DM", "unobtainium"]), "parts.material[1]", "`unobtainium`");
        bad(list(&["ASTM-A401", "EN10270-1-DM", "ASTM-A401"]), "parts.material[2]", "listed twice (also item 0)");
        bad(PartsSettings { grade: 4, ..Default::default() }, "parts.grade", "1, 2 or 3");
        bad(PartsSettings { safety_factor: 0.5, ..Default::default() }, "parts.safety_factor", "from 1");
        bad(PartsSettings { stop_mechanism: "spiral".into(), ..Default::default() }, "parts.stop_mechanism", "drum");
        bad(PartsSettings { trim_mechanism: "screw".into(), ..Default::default() }, "parts.trim_mechanism", "crank");
        bad(PartsSettings { min_pulley_radius_mm: 0.0, ..Default::default() }, "parts.min_pulley_radius_mm", "above 0");
        bad(
            PartsSettings { min_pulley_radius_mm: 50.0, ..Default::default() },
            "parts.min_pulley_radius_mm",
            "above max_pulley_radius_mm",
        );
        bad(PartsSettings { max_joints_crossed: 1, ..Default::default() }, "parts.max_joints_crossed", "from 2");
        let e = ElementEnvelope {
            id: "S01".into(),
            max_outer_diameter_mm: Some(-1.0),
            max_length_mm: None,
            max_lever_mm: None,
        };
        bad(
            PartsSettings { element: vec![e], ..Default::default() },
            "parts.element[0].max_outer_diameter_mm",
            "positive",
        );
    }
}
