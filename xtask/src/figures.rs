//! `cargo xtask figures`: the figures the README quotes, measured and written in one go.
//!
//! Each measurement runs as its own process, the way a user runs it (`cargo xtask
//! bench --scene forest`, `exact`, `sun`, `frame`; the throughput and first-sweep
//! examples; the demo), one after the other so that they do not share the cores; the
//! quick timings (the fly-through, the throughput, the demo) three times each, keeping
//! the run of the median time. Their reports land where they always do
//! (`target/bench/`); this task then writes
//! `docs/figures.md` (every report whole, with the date, the machine and the command)
//! and the README's table of headline figures between the markers
//! `<!-- figures:begin -->` and `<!-- figures:end -->`, both whole or not at all.
//! `--assemble` skips the runs and rebuilds both files from the reports already there.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};

/// The README's markers around the generated table.
pub const BEGIN: &str = "<!-- figures:begin -->";
/// See [`BEGIN`].
pub const END: &str = "<!-- figures:end -->";

/// How a measurement is run.
#[derive(Debug, Clone, Copy)]
enum Runner {
    /// A task of this binary (`cargo xtask ...`), its report in `target/bench/<file>`.
    Xtask(&'static [&'static str], &'static str),
    /// `cargo run --release -p <package> --example <name> -- <args>`, its report on
    /// stdout.
    Example(&'static str, &'static str, &'static [&'static str]),
    /// The demo, headless (`cargo run --release -p lightgrid-viewer`), its report the
    /// summary it writes.
    Demo,
}

/// One measurement: what it measures, how it runs, and its headline lines; for a
/// quick timing (`time`: the seconds or milliseconds its report gives), run
/// [`TIMED_RUNS`] times and the run with the median time kept, as the project states a
/// time (the VM's speed drifts by tens of percent from minute to minute).
struct Measurement {
    what: &'static str,
    command: &'static str,
    runner: Runner,
    headline: fn(&str) -> Vec<String>,
    time: Option<fn(&str) -> Option<f64>>,
}

/// Runs of a timed measurement (one median kept).
const TIMED_RUNS: usize = 3;

fn measurements() -> Vec<Measurement> {
    vec![
        Measurement {
            what: "the sweep against Monte Carlo, bench forest 16³",
            command: "cargo xtask bench --scene forest",
            runner: Runner::Xtask(&["bench", "--scene", "forest"], "bench.txt"),
            headline: |t| lines_starting(t, &["forest: the sweep", "forest, cheapest"]),
            time: None,
        },
        Measurement {
            what: "exact answers",
            command: "cargo xtask exact",
            runner: Runner::Xtask(&["exact"], "exact.txt"),
            headline: exact_headline,
            time: None,
        },
        Measurement {
            what: "the sun kept apart, bench forest 24³",
            command: "cargo xtask sun",
            runner: Runner::Xtask(&["sun"], "sun.txt"),
            headline: sun_headline,
            time: None,
        },
    ]
    .into_iter()
    .chain(hierarchy_measurements())
    .chain([
        Measurement {
            what: "the fly-through, 16-point nodes (sky alone, 30 frames of 12.8 m)",
            command: "cargo run --release -p lightgrid-terrain-lod --example flythrough -- 16",
            runner: Runner::Example("lightgrid-terrain-lod", "flythrough", &["16"]),
            headline: flythrough_headline,
            time: Some(|t| {
                flythrough_headline(t)
                    .first()?
                    .split(' ')
                    .next()?
                    .parse()
                    .ok()
            }),
        },
        Measurement {
            what: "the sweep's throughput (points a second)",
            command: "cargo run --release -p lightgrid-measure --example throughput",
            runner: Runner::Example("lightgrid-measure", "throughput", &[]),
            headline: throughput_headline,
            // Points a second: the median of the first case's rate is the median run.
            time: Some(|t| {
                let rate: f64 = throughput_headline(t)
                    .first()?
                    .split(": ")
                    .nth(1)?
                    .split(' ')
                    .next()?
                    .parse()
                    .ok()?;
                Some(1.0 / rate)
            }),
        },
        Measurement {
            what: "a process's first sweep against a recycled one",
            command: "cargo run --release -p lightgrid-measure --example first_sweep",
            runner: Runner::Example("lightgrid-measure", "first_sweep", &[]),
            headline: |t| lines_starting(t, &["32^3 canopy"]),
            time: None,
        },
        Measurement {
            what: "the demo, headless",
            command: "cargo run --release -p lightgrid-viewer",
            runner: Runner::Demo,
            headline: |t| {
                t.lines()
                    .filter(|l| l.trim_start().starts_with("total"))
                    .map(|l| format!("{} s in all", l.split_whitespace().last().unwrap_or("?")))
                    .collect()
            },
            time: Some(demo_seconds),
        },
    ])
    .collect()
}

/// The hierarchy's measurements: along the camera path (16-point nodes), under a frame
/// budget, and its nesting at the library's defaults.
fn hierarchy_measurements() -> [Measurement; 3] {
    [
        Measurement {
            what: "the hierarchy along a camera path, 16-point nodes",
            command: "cargo xtask frame",
            runner: Runner::Xtask(&["frame"], "frame.txt"),
            headline: |t| {
                t.lines()
                    .filter(|l| {
                        (l.starts_with("sun ") && l.contains("a frame"))
                            || l.trim_start().starts_with("sun +20")
                            || l.trim_start().starts_with("total against Monte Carlo")
                            || (l.trim_start().starts_with("nesting alone at sun")
                                && !l.contains("largest error"))
                    })
                    .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
                    .collect()
            },
            time: None,
        },
        Measurement {
            what: "the hierarchy's nesting at the library's defaults (32-point nodes, an apron of 6 cells, the sun's responses over 3 of them, two nodes a frame with their aprons)",
            command: "cargo xtask frame --node-points 32 --elevation 15 --elevation 40 --mc-probes 0 --out target/bench/nesting",
            runner: Runner::Xtask(
                &[
                    "frame",
                    "--node-points",
                    "32",
                    "--elevation",
                    "15",
                    "--elevation",
                    "40",
                    "--mc-probes",
                    "0",
                    "--out",
                    "target/bench/nesting",
                ],
                "nesting/frame.txt",
            ),
            headline: |t| {
                t.lines()
                    .filter(|l| {
                        let l = l.trim_start();
                        l.starts_with("nesting alone at sun") || l.starts_with("far probes")
                    })
                    .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
                    .collect()
            },
            time: None,
        },
        Measurement {
            what: "time of day under a 30 ms frame budget, 16-point nodes",
            command: "cargo xtask frame --budget-ms 30 --mc-probes 0 --out target/bench/budget",
            runner: Runner::Xtask(
                &[
                    "frame",
                    "--budget-ms",
                    "30",
                    "--mc-probes",
                    "0",
                    "--out",
                    "target/bench/budget",
                ],
                "budget/frame.txt",
            ),
            headline: |t| {
                t.lines()
                    .filter(|l| {
                        (l.starts_with("sun ") && l.contains("a frame"))
                            || l.trim_start().starts_with("sun +20")
                            || l.trim_start().starts_with("every wanted node's sun")
                    })
                    .map(|l| {
                        // The frame's error lines are the plain run's (above); the
                        // budget's own figures are its times and the move's.
                        let l = l.split(", sky bias").next().unwrap_or(l);
                        l.split_whitespace().collect::<Vec<_>>().join(" ")
                    })
                    .collect()
            },
            time: None,
        },
    ]
}

/// The lines of `text` that start with one of `prefixes`, trimmed.
fn lines_starting(text: &str, prefixes: &[&str]) -> Vec<String> {
    text.lines()
        .filter(|l| prefixes.iter().any(|p| l.trim_start().starts_with(p)))
        .map(|l| l.trim().to_string())
        .collect()
}

/// The fly-through example's headline: its table row (time a frame with the
/// hierarchy's set-up, points swept) and the line after it (the frames alone, stages).
fn flythrough_headline(text: &str) -> Vec<String> {
    let mut lines = text
        .lines()
        .skip_while(|l| !l.trim_start().starts_with("16 |"));
    let row = lines.next().map(|l| {
        let f: Vec<&str> = l.split('|').map(str::trim).collect();
        let at = |i: usize| f.get(i).copied().unwrap_or("?");
        format!(
            "{} ms a frame with the set-up ({} points swept in {} frames, {} s)",
            at(3),
            at(4),
            at(1),
            at(2)
        )
    });
    row.into_iter()
        .chain(lines.next().map(|l| l.trim().to_string()))
        .collect()
}

/// The throughput example's headline: per case, millions of points a second into
/// recycled memory and into fresh memory (its last three columns are recycled, fresh and
/// the scalar oracle).
fn throughput_headline(text: &str) -> Vec<String> {
    text.lines()
        .filter(|l| l.contains("canopy"))
        .filter_map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            (w.len() > 3).then(|| {
                let case = w[..w.len() - 3].join(" ");
                format!(
                    "{case}: {} M points/s recycled, {} fresh",
                    w[w.len() - 3],
                    w[w.len() - 2]
                )
            })
        })
        .collect()
}

/// The exact-answer report's headline: the furnace's and the ground's largest error,
/// the half-space albedo's range (the default medium rule).
fn exact_headline(text: &str) -> Vec<String> {
    let error_of = |l: &str| -> Option<f64> {
        l.split_whitespace()
            .find(|w| w.ends_with('%'))
            .and_then(|w| w.trim_end_matches('%').parse().ok())
    };
    let largest = |pick: &dyn Fn(&str) -> bool| -> Option<f64> {
        text.lines()
            .filter(|l| pick(l))
            .filter_map(error_of)
            .map(f64::abs)
            .reduce(f64::max)
    };
    let half: Vec<f64> = text
        .lines()
        .filter(|l| l.starts_with("half-space w") && !l.contains("flat source"))
        .filter_map(error_of)
        .collect();
    let mut out = Vec::new();
    if let Some(f) = largest(&|l: &str| l.starts_with("furnace")) {
        out.push(format!("white furnace: largest error {f:.1} %"));
    }
    if let Some(g) = largest(&|l: &str| l.contains("Lambertian ground")) {
        out.push(format!("Lambertian ground: error {g:.1} %"));
    }
    if let (Some(lo), Some(hi)) = (
        half.iter().copied().reduce(f64::min),
        half.iter().copied().reduce(f64::max),
    ) {
        out.push(format!(
            "Chandrasekhar's half-space albedo: {lo:+.1} to {hi:+.1} %"
        ));
    }
    out
}

/// The sun report's headline: the irradiance error's range with the sun kept apart and
/// with it in the bins, and the reference's noise, over the forest's elevations.
fn sun_headline(text: &str) -> Vec<String> {
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip_while(|l| !l.starts_with("elev  azim   bins avg"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .map(|l| {
            l.split_whitespace()
                .filter_map(|w| w.parse().ok())
                .collect()
        })
        .filter(|r: &Vec<f64>| r.len() >= 7)
        .collect();
    let range = |i: usize| {
        let v = rows.iter().map(|r| r[i]);
        let lo = v.clone().fold(f64::INFINITY, f64::min);
        let hi = v.fold(f64::NEG_INFINITY, f64::max);
        format!("{lo:.3}–{hi:.3}")
    };
    if rows.is_empty() {
        return Vec::new();
    }
    vec![format!(
        "irradiance RMSE {} with the sun kept apart, {} with the sun in the bins; reference noise {}",
        range(5),
        range(3),
        range(6)
    )]
}

/// The demo summary's total, seconds.
fn demo_seconds(text: &str) -> Option<f64> {
    text.lines()
        .find(|l| l.trim_start().starts_with("total"))?
        .split_whitespace()
        .last()?
        .parse()
        .ok()
}

/// Where a measurement's report is kept: `target/bench/...` (the demo's whole output
/// folder for the demo).
fn report_path(root: &Path, runner: Runner) -> PathBuf {
    match runner {
        Runner::Xtask(_, file) => root.join("target/bench").join(file),
        Runner::Example(_, name, _) => root.join("target/bench").join(format!("{name}.txt")),
        Runner::Demo => root.join("target/figures-demo/summary.txt"),
    }
}

/// Runs `m` once; its report's text. An example's report is saved at
/// [`report_path`]; the demo writes its output folder `out` (relative to `root`), the
/// xtask tasks their reports where they always do.
fn run_once(root: &Path, m: &Measurement, out: &str) -> Result<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!("figures: {}", m.command);
    match m.runner {
        Runner::Xtask(args, _) => {
            let me = std::env::current_exe().context("the xtask binary")?;
            let status = Command::new(&me)
                .args(args)
                .current_dir(root)
                .status()
                .with_context(|| m.command.to_string())?;
            if !status.success() {
                bail!("{} failed ({status})", m.command);
            }
            let p = report_path(root, m.runner);
            std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))
        }
        Runner::Example(package, name, args) => {
            let out = Command::new(&cargo)
                .args(["run", "--release", "-q", "-p", package, "--example", name])
                .arg("--")
                .args(args)
                .current_dir(root)
                .output()
                .with_context(|| m.command.to_string())?;
            if !out.status.success() {
                bail!(
                    "{} failed: {}",
                    m.command,
                    String::from_utf8_lossy(&out.stderr)
                );
            }
            Ok(String::from_utf8_lossy(&out.stdout).into_owned())
        }
        Runner::Demo => {
            let status = Command::new(&cargo)
                .args(["run", "--release", "-q", "-p", "lightgrid-viewer", "--"])
                // Relative to the root it runs in: the summary's file list names no
                // machine's paths.
                .arg("--out")
                .arg(out)
                .current_dir(root)
                .env("LIGHTGRID_QUIET", "1")
                .status()
                .with_context(|| m.command.to_string())?;
            if !status.success() {
                bail!("{} failed ({status})", m.command);
            }
            let p = root.join(out).join("summary.txt");
            std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))
        }
    }
}

/// Runs `m` ([`TIMED_RUNS`] times where it is timed, keeping the run of the median
/// time) and keeps its report at [`report_path`]; the report's text.
fn measure(root: &Path, m: &Measurement) -> Result<String> {
    let Some(time) = m.time else {
        let text = run_once(root, m, "target/figures-demo")?;
        if let Runner::Example(..) = m.runner {
            lightgrid_core::file::write_atomic(&report_path(root, m.runner), text.as_bytes())?;
        }
        return Ok(text);
    };
    let mut runs = Vec::with_capacity(TIMED_RUNS);
    for i in 0..TIMED_RUNS {
        let out = format!("target/figures-demo-run{i}");
        let text = run_once(root, m, &out)?;
        let t = time(&text).with_context(|| format!("{}: no time in its report", m.command))?;
        runs.push((t, i, text));
    }
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (_, i, mut text) = runs.swap_remove(TIMED_RUNS / 2);
    match m.runner {
        Runner::Demo => {
            // The median run's whole folder becomes the demo's output.
            let keep = root.join("target/figures-demo");
            if keep.exists() {
                std::fs::remove_dir_all(&keep)
                    .with_context(|| format!("removing {}", keep.display()))?;
            }
            std::fs::rename(root.join(format!("target/figures-demo-run{i}")), &keep)
                .context("keeping the demo's median run")?;
            // Its summary names the folder it ran into: the one it is kept as.
            for name in ["summary.txt", "summary.json"] {
                let p = keep.join(name);
                let t = std::fs::read_to_string(&p)
                    .with_context(|| format!("reading {}", p.display()))?
                    .replace(
                        &format!("target/figures-demo-run{i}"),
                        "target/figures-demo",
                    );
                lightgrid_core::file::write_atomic(&p, t.as_bytes())?;
                if name == "summary.txt" {
                    text = t;
                }
            }
            for j in (0..TIMED_RUNS).filter(|&j| j != i) {
                let _ = std::fs::remove_dir_all(root.join(format!("target/figures-demo-run{j}")));
            }
        }
        _ => lightgrid_core::file::write_atomic(&report_path(root, m.runner), text.as_bytes())?,
    }
    Ok(text)
}

/// Runs every measurement (unless `assemble_only`), then writes `docs/figures.md` and
/// the README's table. Returns the paths written.
pub fn run(root: &Path, assemble_only: bool) -> Result<Vec<PathBuf>> {
    let mut reports = Vec::new();
    for m in measurements() {
        let text = if assemble_only {
            let p = report_path(root, m.runner);
            std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))?
        } else {
            measure(root, &m)?
        };
        let headline = (m.headline)(&text);
        if headline.is_empty() {
            bail!("{}: no headline figures found in its report", m.command);
        }
        reports.push((m, text, headline));
    }
    let machine = machine();
    let date = date();
    let mut doc = format!(
        "# Figures\n\nWritten by `cargo xtask figures` on {date}, on {machine}; each \
         measurement ran alone, one after the other. The README's table of figures is \
         made from the same runs. Run it again to bring both up to date.\n"
    );
    let mut table = String::from("| what | figures | command |\n|------|---------|---------|\n");
    for (m, text, headline) in &reports {
        let what = match m.time {
            Some(_) => format!("{} (the median of {TIMED_RUNS} runs)", m.what),
            None => m.what.to_string(),
        };
        doc += &format!(
            "\n## {}\n\n`{}`\n\n```text\n{}\n```\n",
            what,
            m.command,
            text.trim_end()
        );
        table += &format!(
            "| {} | {} | `{}` |\n",
            what,
            headline.join("; ").replace('|', "/"),
            m.command
        );
    }
    let readme_path = root.join("README.md");
    let readme = std::fs::read_to_string(&readme_path).context("reading README.md")?;
    let (Some(b), Some(e)) = (readme.find(BEGIN), readme.find(END)) else {
        bail!("README.md lacks the markers {BEGIN} and {END}");
    };
    if e < b {
        bail!("README.md: {END} comes before {BEGIN}");
    }
    let readme = format!(
        "{}{BEGIN}\nMeasured by `cargo xtask figures` on {date}, on {machine}; every report \
         whole in [docs/figures.md](docs/figures.md).\n\n{table}{}",
        &readme[..b],
        &readme[e..]
    );
    let doc_path = root.join("docs/figures.md");
    lightgrid_core::file::write_all_atomic(&[
        (doc_path.clone(), doc.as_bytes()),
        (readme_path.clone(), readme.as_bytes()),
    ])?;
    Ok(vec![doc_path, readme_path])
}

/// The machine in words: CPU model and logical cores.
fn machine() -> String {
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|c| {
            c.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    format!("{cores} cores ({model})")
}

/// Today's date (UTC), from the system clock.
fn date() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headlines_are_read_from_the_reports_formats() {
        let exact = "furnace 12³: average light  1.0000 1.0000 +0.0% 43\n\
                     one-level Lambertian ground, albedo 0.3  0.3000 0.3000 +0.0% 2\n\
                     half-space w 0.1, cell optical depth 0.05  0.0164 0.0167 +1.7% 5\n\
                     half-space w 0.99, cell optical depth 3.00  0.7527 0.7526 -0.1% 184\n\
                     half-space w 0.1, cell optical depth 3.00, flat source 0.0164 0.0126 -23.2% 4\n";
        assert_eq!(
            exact_headline(exact),
            [
                "white furnace: largest error 0.0 %",
                "Lambertian ground: error 0.0 %",
                "Chandrasekhar's half-space albedo: -0.1 to +1.7 %"
            ]
        );
        let sun = "elev  azim   bins avg  bins irr   split avg  split irr   ref noise   bins s  split s\n\
                     10    20     0.0768    0.2933      0.0231     0.0222      0.0309    0.090    0.032\n\
                     80    20     0.0382    0.1549      0.0258     0.0276      0.0338    0.015    0.018\n\n";
        assert_eq!(
            sun_headline(sun),
            [
                "irradiance RMSE 0.022–0.028 with the sun kept apart, 0.155–0.293 with the sun in the bins; reference noise 0.031–0.034"
            ]
        );
    }

    #[test]
    fn throughput_lines_name_their_columns() {
        let t = "case  recycled Mpt/s   fast Mpt/s oracle Mpt/s\n\
                 64^3 canopy, 26 bins, 4 passes               4.81         5.11         0.56\n";
        assert_eq!(
            throughput_headline(t),
            ["64^3 canopy, 26 bins, 4 passes: 4.81 M points/s recycled, 5.11 fresh"]
        );
    }

    #[test]
    fn the_flythrough_row_and_its_breakdown_are_read() {
        let t = "node points | frames | total s | ms/frame | points swept | 26-bin f32 MB\n  frame  0: swept 23552 points\n         16 |     30 |    1.48 |     49.3 |       549888 |          61.6\n              of which setup (Hierarchy::new) 132 ms, the frames 44.9 ms a frame\n";
        assert_eq!(
            flythrough_headline(t),
            [
                "49.3 ms a frame with the set-up (549888 points swept in 30 frames, 1.48 s)",
                "of which setup (Hierarchy::new) 132 ms, the frames 44.9 ms a frame"
            ]
        );
        assert!(flythrough_headline("no table").is_empty());
    }

    #[test]
    fn timed_measurements_read_their_time() {
        let time = |what: &str, text: &str| {
            let m = measurements()
                .into_iter()
                .find(|m| m.what.starts_with(what));
            (m.and_then(|m| m.time).expect("a timed measurement"))(text)
        };
        let fly = "         16 |     30 |    1.48 |     49.3 |       549888 |          61.6\n";
        assert_eq!(time("the fly-through", fly), Some(49.3));
        let tp = "case  recycled Mpt/s   fast Mpt/s oracle Mpt/s\n\
                  64^3 canopy, 26 bins, 1 pass               12.5         5.11         0.56\n";
        assert_eq!(time("the sweep's throughput", tp), Some(1.0 / 12.5));
        assert_eq!(
            time("the demo", "stages (seconds):\n  total   7.85\n"),
            Some(7.85)
        );
        assert_eq!(time("the demo", "no total"), None);
    }

    #[test]
    fn the_date_is_a_civil_date() {
        let d = date();
        assert_eq!(d.len(), 10);
        assert!(d.starts_with("20"), "{d}");
    }
}
