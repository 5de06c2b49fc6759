//! The files `springfit geodesics` writes.

use super::figures::geodesics_figure;
use super::output::OutputDir;
use super::plot::render;
use crate::design::Design;
use crate::error::Result;
use crate::geodesic::{Fan, RegionReport};

/// `geodesics.csv`: direction, s, q…, q̇… for every sample of every geodesic.
pub fn geodesics_csv(fan: &Fan) -> String {
    let n = fan.q_eq.len();
    let mut s = String::from("direction,s");
    for i in 1..=n {
        s.push_str(&format!(",q{i}"));
    }
    for i in 1..=n {
        s.push_str(&format!(",qd{i}"));
    }
    s.push('\n');
    for (d, g) in fan.geodesics.iter().enumerate() {
        for k in 0..g.len() {
            s.push_str(&format!("{d},{}", g.s(k)));
            for v in g.q(k).iter().chain(g.qd(k)) {
                s.push_str(&format!(",{v}"));
            }
            s.push('\n');
        }
    }
    s
}

/// The names `springfit geodesics` may write (see [`super::output::Plan`]).
pub const FILES: &[&str] = &["geodesics.csv", "region.json", "geodesics.svg", "geodesics.png"];

/// Writes the geodesics outputs into `out`: the fan's sampled angles (`geodesics.csv`), the region
/// report (`region.json`) and the figure of the fan over the region (`geodesics.svg`, `.png`).
pub fn write(out: &OutputDir, design: &Design, fan: &Fan, region: &RegionReport) -> Result<()> {
    out.write("geodesics.csv", geodesics_csv(fan))?;
    let json = serde_json::to_string_pretty(region).expect("the region report serialises");
    out.write("region.json", json + "\n")?;
    let title = format!("{}: geodesics from q_eq over the {}", design.name, region.region);
    render(&geodesics_figure(design, fan, &title), &out.path("geodesics"))?;
    Ok(())
}
