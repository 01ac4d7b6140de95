//! No function outside tests runs over 150 lines (the house rule: split it by job; the
//! eleven that were longer when the rule came have all been split). Lengths are counted
//! from the `fn` line to the closing brace at its indentation (rustfmt's layout),
//! skipping `#[cfg(test)]` modules, `tests/`, `benches/` and `examples/`.

use std::path::{Path, PathBuf};

use xtask::tree::root;

/// Longest a function may be.
const MAX_LINES: usize = 150;

/// The `.rs` files under `dir` outside `tests/`, `benches/`, `examples/`.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let enter = |name: &str| !["tests", "benches", "examples", "target", ".git"].contains(&name);
    xtask::tree::files(dir, &enter, &|_, name| name.ends_with(".rs"))
}

/// `(function, first line, lines)` of every function in `text` outside test modules.
fn functions(text: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let indent = |l: &str| l.len() - l.trim_start().len();
    let closes = |from: usize, ind: usize| {
        let end = " ".repeat(ind) + "}";
        (from + 1..lines.len()).find(|&k| lines[k] == end)
    };
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let l = lines[i].trim_start();
        if l.starts_with("#[cfg(test)]")
            && let Some(next) = lines.get(i + 1)
            && next.trim_start().contains("mod ")
            && next.trim_end().ends_with('{')
        {
            i = closes(i + 1, indent(next)).map_or(lines.len(), |k| k + 1);
            continue;
        }
        let words: Vec<&str> = l.split_whitespace().collect();
        if let Some(at) = words.iter().position(|w| *w == "fn")
            && words[..at]
                .iter()
                .all(|w| w.starts_with("pub") || ["const", "unsafe", "async", "extern"].contains(w))
            && !lines[i].trim_end().ends_with(';')
            && let Some(name) = words.get(at + 1)
        {
            let name: String = name
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if let Some(k) = closes(i, indent(lines[i])) {
                out.push((name, i + 1, k - i + 1));
            }
        }
        i += 1;
    }
    out
}

#[test]
fn the_counter_finds_functions_and_skips_test_modules() {
    let text = "fn a() {\n    x();\n}\n\npub(crate) fn b(\n    y: u32,\n) -> u32 {\n    y\n}\n#[cfg(test)]\nmod tests {\n    fn c() {\n    }\n}\n";
    let f = functions(text);
    assert_eq!(f, vec![("a".to_string(), 1, 3), ("b".to_string(), 5, 5)]);
}

#[test]
fn no_function_outside_tests_runs_over_150_lines() {
    let root = root();
    let files: Vec<PathBuf> = ["crates", "xtask/src"]
        .iter()
        .flat_map(|dir| sources(&root.join(dir)))
        .collect();
    assert!(files.len() > 50, "found {} source files", files.len());
    let mut bad = Vec::new();
    for file in &files {
        let rel = file
            .strip_prefix(&root)
            .unwrap_or(file)
            .to_string_lossy()
            .replace('\\', "/");
        let text = std::fs::read_to_string(file).unwrap();
        for (name, line, n) in functions(&text) {
            if n > MAX_LINES {
                bad.push(format!(
                    "{rel}:{line} {name}: {n} lines (at most {MAX_LINES})"
                ));
            }
        }
    }
    assert!(bad.is_empty(), "split these by job:\n{}", bad.join("\n"));
}
