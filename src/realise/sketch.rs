//! A dimensioned sketch of each mechanism (SVG, mm to scale within the sketch): what the
//! builder mounts and the dimensions the request for quotation names.

use std::fmt::Write as _;

use super::mechanism::{Mechanism, Part, Spring};
use super::spring::{HelicalSpring, TorsionSpring};

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// A zig-zag spring from (x0, y) to (x1, y), `coils` peaks of half-height `h`.
fn zigzag(x0: f64, x1: f64, y: f64, h: f64, coils: usize) -> String {
    let mut p = format!("M{x0:.2},{y:.2} ");
    let n = 2 * coils.max(2);
    for i in 1..n {
        let x = x0 + (x1 - x0) * i as f64 / n as f64;
        let dy = if i % 2 == 1 { -h } else { h };
        let _ = write!(p, "L{x:.2},{:.2} ", y + dy);
    }
    let _ = write!(p, "L{x1:.2},{y:.2}");
    format!("<path d=\"{p}\" fill=\"none\" stroke=\"#a33\" stroke-width=\"1.5\"/>")
}

/// Width and height of every sketch, px.
const SKETCH_SIZE: (f64, f64) = (420.0, 260.0);

/// A line of text at (x, y).
fn text(b: &mut String, x: f64, y: f64, s: &str) {
    let _ =
        writeln!(b, "<text x=\"{x:.1}\" y=\"{y:.1}\" font-size=\"11\" font-family=\"sans-serif\">{}</text>", esc(s));
}

/// The units of a part's working points: (position, load).
pub fn units(p: &Part) -> (&'static str, &'static str) {
    match p.spring {
        Spring::Torsion(_) => ("deg", "N*mm"),
        Spring::Leaf { .. } => ("mm tip deflection", "N"),
        _ => ("mm length", "N"),
    }
}

/// The spring's free length (compression, extension with its loops; a leaf's at mid-range) and
/// leg length (torsion), mm.
pub fn lengths(s: &Spring) -> (Option<f64>, Option<f64>) {
    match s {
        Spring::Torsion(t) => (None, Some(t.leg)),
        Spring::Extension(h, _) => (Some(h.extension_free_length()), None),
        Spring::Compression(_, l0) => (Some(*l0), None),
        Spring::Leaf { lengths, .. } => (Some(lengths[2]), None),
    }
}

/// What a spring maker reads off a drawing, in the order of a DIN 2099 data sheet (part 1
/// compression, part 2 extension; torsion and leaf springs alike): the wire and its coil
/// diameters, the free length or the legs, the coils, the rate with its EN 15800 grade, every
/// working point, then material and surface. `grade` is `[parts] grade` and `surface` the
/// surface's name (as wound, shot peened): neither is the part's own, the design sets them.
/// `order` says how it is bought (a stock part's vendor and number, or wound to the sheet).
pub fn data_block(part: &Part, grade: u8, surface: &str, order: &str) -> Vec<String> {
    let s = &part.spring;
    let mut rows = vec![format!("{} × {} spring, {order}", part.quantity, s.kind())];
    match *s {
        Spring::Leaf { t, b, lengths, .. } => {
            rows.push(format!("strip t × b = {t} × {b} mm"));
            rows.push(format!("free length {:.1} – {:.1} mm (mid-range {:.1} mm)", lengths[0], lengths[1], lengths[2]));
        }
        _ => {
            let (d, dm) = (s.d(), s.dm());
            rows.push(format!("d = {d} mm, D = {dm:.2} mm, De = {:.2} mm, Di = {:.2} mm", dm + d, dm - d));
            let coils = s.coils().unwrap_or(0.0);
            rows.push(match lengths(s) {
                (Some(l0), _) => format!("L0 = {l0:.1} mm, n = {coils:.2} active coils"),
                (None, Some(leg)) => format!("legs 2 × {leg:.1} mm from the coil axis, n = {coils:.2} body coils"),
                (None, None) => format!("n = {coils:.2} active coils"),
            });
        }
    }
    if let Spring::Extension(_, f0) = s {
        rows.push(format!("initial tension F0 = {f0:.2} N, full loop at each end"));
    }
    let (rate, unit) = s.maker_rate();
    rows.push(format!(
        "rate {rate:.4} {}, ±{:.1} % (EN 15800 grade {grade})",
        unit.replace('*', "·").replace("deg", "°"),
        100.0 * part.tolerance
    ));
    let (pu, lu) = units(part);
    let (pu, lu) = (pu.replace("deg", "°").replace(" length", ""), lu.replace('*', "·"));
    for w in &part.points {
        rows.push(format!("{}: {:.2} {pu} at {:.2} {lu}", w.at, w.position, w.load));
    }
    rows.push(format!("material {}, surface {surface}", s.material()));
    rows
}

/// Height of one line of the data block, px.
const LINE: f64 = 15.0;

/// The sketch of `part` titled `title` (empty when the part's spring is not its mechanism's),
/// with its data block ([`data_block`]: `grade`, `surface`, `order`) under the drawing.
pub fn svg(part: &Part, title: &str, grade: u8, surface: &str, order: &str) -> String {
    let block = data_block(part, grade, surface, order);
    let (w, drawing) = SKETCH_SIZE;
    let h = drawing + 10.0 + LINE * block.len() as f64;
    let s = &part.spring;
    let body = match (part.mechanism, *s) {
        (Mechanism::Crank { r, big_r, pulley, .. }, _) => crank(r, big_r, pulley),
        (Mechanism::TrimCrank { r, big_r, pulley, .. }, _) => crank(r[1], big_r, pulley),
        (Mechanism::Leaf { lever, gear }, Spring::Leaf { t, b, lengths, .. }) => {
            leaf(part.quantity, lever, gear, t, b, lengths)
        }
        (Mechanism::Follower | Mechanism::CubicCam { .. } | Mechanism::DrumStop { .. }, Spring::Compression(c, l0)) => {
            follower(&c, l0)
        }
        (Mechanism::TorsionPair { .. } | Mechanism::TorsionStop { .. }, Spring::Torsion(t)) => {
            torsion(&t, matches!(part.mechanism, Mechanism::TorsionStop { .. }))
        }
        _ => return String::new(),
    };
    let mut body = body;
    let _ =
        writeln!(body, "<line x1=\"10\" y1=\"{drawing}\" x2=\"{:.1}\" y2=\"{drawing}\" stroke=\"#888\"/>", w - 10.0);
    for (i, row) in block.iter().enumerate() {
        text(&mut body, 14.0, drawing + LINE * (i as f64 + 1.0), row);
    }
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n<title>{}</title>\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n<text x=\"10\" y=\"18\" font-size=\"13\" font-family=\"sans-serif\" font-weight=\"bold\">{}</text>\n{body}</svg>\n",
        esc(title),
        esc(title)
    )
}

/// A crank: the crank axis O, the pin at r (drawn 40° off the anchor line), the fairlead at R
/// with its rollers, the spring beyond it.
fn crank(r: f64, big_r: f64, pulley: f64) -> String {
    let mut body = String::new();
    let scale = 150.0 / (big_r + r);
    let (ox, oy) = (70.0, 140.0);
    let a = 40f64.to_radians();
    let (px, py) = (ox + scale * r * a.cos(), oy - scale * r * a.sin());
    let ax = ox + scale * big_r;
    let _ = writeln!(
        body,
        "<circle cx=\"{ox}\" cy=\"{oy}\" r=\"{:.1}\" fill=\"none\" stroke=\"#555\" stroke-dasharray=\"4,3\"/>\
         <line x1=\"{ox}\" y1=\"{oy}\" x2=\"{px:.1}\" y2=\"{py:.1}\" stroke=\"#000\" stroke-width=\"3\"/>\
         <circle cx=\"{px:.1}\" cy=\"{py:.1}\" r=\"3\" fill=\"#000\"/>\
         <circle cx=\"{ax:.1}\" cy=\"{:.1}\" r=\"{:.1}\" fill=\"none\" stroke=\"#000\"/>\
         <circle cx=\"{ax:.1}\" cy=\"{:.1}\" r=\"{:.1}\" fill=\"none\" stroke=\"#000\"/>\
         <line x1=\"{px:.1}\" y1=\"{py:.1}\" x2=\"{ax:.1}\" y2=\"{oy}\" stroke=\"#36c\"/>\
         <line x1=\"{ax:.1}\" y1=\"{oy}\" x2=\"{:.1}\" y2=\"{oy}\" stroke=\"#36c\"/>",
        scale * r,
        oy - scale * pulley,
        (scale * pulley).max(1.5),
        oy + scale * pulley,
        (scale * pulley).max(1.5),
        ax + 20.0
    );
    body.push_str(&zigzag(ax + 20.0, SKETCH_SIZE.0 - 20.0, oy, 8.0, 8));
    text(&mut body, ox - 10.0, oy + 20.0, "O (axis)");
    text(&mut body, px - 10.0, py - 8.0, &format!("pin, r = {r} mm"));
    text(&mut body, ax - 20.0, oy + 28.0, &format!("fairlead, R = {big_r} mm, rollers ρ = {pulley} mm"));
    body
}

/// A leaf `t` × `b` mm in a sliding clamp (free lengths `lengths`: the rate range's ends and
/// mid-range), its tip roller on a lever geared down from x; a stack of `quantity` leaves in
/// the one clamp is drawn as one leaf and counted in the label.
fn leaf(quantity: usize, lever: f64, gear: f64, t: f64, b: f64, lengths: [f64; 3]) -> String {
    let mut body = String::new();
    let scale = 260.0 / lengths[1].max(1.0);
    let (cx, y) = (60.0, 120.0);
    let _ = writeln!(
        body,
        "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"24\" height=\"30\" fill=\"#ccc\" stroke=\"#000\"/>\
         <line x1=\"{cx}\" y1=\"{y}\" x2=\"{:.1}\" y2=\"{y}\" stroke=\"#a33\" stroke-width=\"3\"/>\
         <circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"5\" fill=\"none\" stroke=\"#000\"/>",
        cx - 12.0,
        y - 15.0,
        cx + scale * lengths[1],
        cx + scale * lengths[1],
        y + 6.0
    );
    text(&mut body, cx - 30.0, y + 35.0, &format!("sliding clamp: free length {:.1}–{:.1} mm", lengths[0], lengths[1]));
    let stack = if quantity > 1 { format!("{quantity} × ") } else { String::new() };
    let label = format!("{stack}leaf {t} × {b} mm, set at {:.1} mm for mid-range", lengths[2]);
    text(&mut body, cx, y - 25.0, &label);
    text(&mut body, cx, y + 60.0, &format!("tip roller on a {lever} mm lever, geared {gear:.2} : 1"));
    body
}

/// A cam follower's compression spring of free length `l0` (mm).
fn follower(c: &HelicalSpring, l0: f64) -> String {
    let mut body = String::new();
    let scale = 300.0 / l0.max(1.0);
    body.push_str(&zigzag(50.0, 50.0 + scale * l0, 120.0, (scale * c.dm / 2.0).clamp(6.0, 50.0), c.n.round() as usize));
    text(&mut body, 50.0, 200.0, &format!("L0 = {l0:.1} mm, d = {} mm, D = {:.1} mm, n = {:.2}", c.d, c.dm, c.n));
    body
}

/// A torsion spring seen along its axis with its legs and arbor, and its dimensions: one
/// against a stop at x₀ (`stop`) or two wound against each other.
fn torsion(t: &TorsionSpring, stop: bool) -> String {
    let mut body = String::new();
    let (cx, cy) = (130.0, 130.0);
    let ro = 80.0;
    let ri = ro * (t.dm - t.d) / (t.dm + t.d);
    let _ = writeln!(
        body,
        "<circle cx=\"{cx}\" cy=\"{cy}\" r=\"{ro:.1}\" fill=\"none\" stroke=\"#a33\" stroke-width=\"2\"/>\
         <circle cx=\"{cx}\" cy=\"{cy}\" r=\"{ri:.1}\" fill=\"none\" stroke=\"#a33\" stroke-width=\"2\"/>\
         <circle cx=\"{cx}\" cy=\"{cy}\" r=\"{:.1}\" fill=\"#ddd\" stroke=\"#000\"/>\
         <line x1=\"{:.1}\" y1=\"{cy}\" x2=\"{:.1}\" y2=\"{cy}\" stroke=\"#a33\" stroke-width=\"2\"/>\
         <line x1=\"{cx}\" y1=\"{:.1}\" x2=\"{cx}\" y2=\"{:.1}\" stroke=\"#a33\" stroke-width=\"2\"/>",
        ri * 0.9 * 0.6,
        cx + ro,
        cx + ro + 60.0,
        cy - ro,
        cy - ro - 40.0
    );
    if stop {
        let _ = writeln!(
            body,
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"8\" height=\"14\" fill=\"#333\"/>",
            cx + ro + 50.0,
            cy + 2.0
        );
        text(&mut body, cx + ro + 10.0, cy + 30.0, "stop at x₀");
    } else {
        text(&mut body, cx + ro + 5.0, cy + 30.0, "× 2, wound against each other");
    }
    text(&mut body, 250.0, 60.0, &format!("d = {} mm", t.d));
    text(&mut body, 250.0, 76.0, &format!("D = {:.1} mm (OD {:.1})", t.dm, t.outer_diameter()));
    text(&mut body, 250.0, 92.0, &format!("n = {:.2}, legs {:.0} mm", t.n, t.leg));
    text(&mut body, 250.0, 108.0, &format!("rate {:.3} N·mm/°", t.rate_per_degree()));
    body
}
