//! `cargo xtask <task>`: project chores.
//!
//! * `inspect <file>`: prints the header of a grid file and a summary of its values.
//!
//! `bench` (run time against error) arrives with the benchmark issue.

use std::process::ExitCode;

use grid_core::{GridFile, LightGrid};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args
        .iter()
        .map(String::as_str)
        .collect::<Vec<_>>()
        .as_slice()
    {
        ["inspect", path] => match GridFile::load(path) {
            Ok(f) => {
                print!("{}", describe(&f));
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("xtask inspect: {e}");
                ExitCode::FAILURE
            }
        },
        _ => {
            eprintln!("usage: cargo xtask inspect <grid file>");
            ExitCode::FAILURE
        }
    }
}

fn describe(f: &GridFile) -> String {
    let (desc, extra) = match f {
        GridFile::Material(g) => {
            let filled = g.data().iter().filter(|m| !m.is_empty()).count();
            (*g.desc(), format!("cells with material: {filled}\n"))
        }
        GridFile::Light(g) => (*g.desc(), light_summary(g)),
        GridFile::PackedLight(p) => (
            *p.grid.desc(),
            format!("exposure: {}\n{}", p.exposure, light_summary(&p.unpack())),
        ),
        GridFile::Average(g) => (*g.desc(), String::new()),
        GridFile::Dominant(g) => (*g.desc(), String::new()),
    };
    format!(
        "kind: {}\norigin: {}\ncell size: {} m\ndims: {}\npoints: {}\n{extra}",
        f.kind().name(),
        desc.origin(),
        desc.h(),
        desc.dims(),
        desc.point_count()
    )
}

fn light_summary(g: &LightGrid) -> String {
    let n = g.data().len().max(1) as f32;
    let mean = g
        .data()
        .iter()
        .map(|b| b.average())
        .sum::<grid_core::glam::Vec3>()
        / n;
    format!(
        "largest bin value: {}\nmean average light: {}\n",
        g.max_value(),
        mean
    )
}
