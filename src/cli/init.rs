//! `springfit init`: a design to run from an arm alone (a URDF and its joints, or planar links).

use std::path::PathBuf;

use anyhow::Result;
use springfit::Error;
use springfit::jobs::init::{InitArm, InitRequest, run as init};

use super::progress::Progress;

/// The command's arguments.
pub struct InitArgs {
    pub out: PathBuf,
    pub urdf: Option<PathBuf>,
    pub joints: Vec<String>,
    pub lock: Vec<String>,
    pub links: Option<String>,
    pub gravity: Option<Vec<f64>>,
    pub q: Option<Vec<f64>>,
}

pub fn run(args: InitArgs, progress: &Progress) -> Result<()> {
    let setting = |field: &str, reason: String| Error::Setting { field: field.into(), reason };
    let arm = match (&args.urdf, &args.links) {
        (Some(urdf), None) => {
            if args.joints.is_empty() {
                return Err(setting("--joints", "name the URDF joints that move, from the base outwards".into()).into());
            }
            let gravity = match args.gravity.as_deref() {
                None => [0.0, 0.0, -9.81],
                Some(&[x, y, z]) => [x, y, z],
                Some(g) => return Err(setting("--gravity", format!("{} numbers: a URDF arm takes 3", g.len())).into()),
            };
            let mut locked = Vec::new();
            for l in &args.lock {
                let (name, value) =
                    l.split_once('=').ok_or_else(|| setting("--lock", format!("`{l}`: write name=value (rad)")))?;
                let value: f64 = value
                    .trim()
                    .parse()
                    .map_err(|_| setting("--lock", format!("`{l}`: {value} is not a number (rad)")))?;
                locked.push((name.trim().to_string(), value));
            }
            InitArm::Urdf { urdf: urdf.clone(), joints: args.joints.clone(), locked, gravity }
        }
        (None, Some(links)) => {
            let gravity = match args.gravity.as_deref() {
                None => [0.0, -9.81],
                Some(&[x, y]) => [x, y],
                Some(g) => {
                    return Err(setting("--gravity", format!("{} numbers: a planar arm takes 2", g.len())).into());
                }
            };
            InitArm::Planar { links: planar_links(links)?, gravity }
        }
        _ => {
            return Err(setting(
                "--urdf",
                "give either --urdf with --joints, or --links (a planar arm): one of the two".into(),
            )
            .into());
        }
    };
    let request = InitRequest { arm, out: args.out, q_eq: args.q };
    let step = progress.step("reading the arm, checking how far its region can reach");
    let result = init(&request);
    step.finish();
    let run = result?;
    run.write()?;
    progress.say(format!("wrote {} and {}", run.design_path.display(), run.catalog_path.display()));
    for n in &run.notes {
        progress.say(format!("  {n}"));
    }
    progress.say(format!("next: springfit check {0}, then springfit fit {0}", run.design_path.display()));
    Ok(())
}

/// Planar links as `mass,length,com,inertia;…`, or a file of one link a line (four numbers
/// separated by commas or spaces; `#` starts a comment).
fn planar_links(spec: &str) -> Result<Vec<[f64; 4]>> {
    let path = std::path::Path::new(spec);
    let (text, sep, what) = if path.is_file() {
        (std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?, '\n', format!("{spec}: line"))
    } else {
        (spec.to_string(), ';', "--links: link".to_string())
    };
    let mut links = Vec::new();
    for (i, line) in text.split(sep).enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let numbers: Vec<f64> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(str::parse)
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| Error::Setting {
                field: "--links".into(),
                reason: format!("{what} {}: `{line}` is not four numbers", i + 1),
            })?;
        let [m, l, c, inertia] = numbers[..] else {
            return Err(Error::Setting {
                field: "--links".into(),
                reason: format!(
                    "{what} {}: mass, length, com and inertia, four numbers (got {})",
                    i + 1,
                    numbers.len()
                ),
            }
            .into());
        };
        links.push([m, l, c, inertia]);
    }
    Ok(links)
}
