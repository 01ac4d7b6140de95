//! Output paths checked before any work is done: an output never replaces an input,
//! two outputs never share a file, and an existing output must be a regular file (a
//! folder, device or pipe is refused, not replaced by a rename).

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

/// `p` as the file system resolves it: canonical where it exists, else its canonical
/// folder and its name (so `x`, `./x` and `dir/../x` compare equal).
fn resolved(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    let parent = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match (parent.canonicalize(), p.file_name()) {
        (Ok(d), Some(name)) => d.join(name),
        _ => p.to_path_buf(),
    }
}

/// Refuses outputs equal to an input or to each other, and outputs that exist and are
/// not regular files. Errors name the paths.
pub(crate) fn check(inputs: &[&Path], outputs: &[&Path]) -> Result<()> {
    let ins: Vec<PathBuf> = inputs.iter().map(|p| resolved(p)).collect();
    let outs: Vec<PathBuf> = outputs.iter().map(|p| resolved(p)).collect();
    for (i, (o, given)) in outs.iter().zip(outputs).enumerate() {
        if let Ok(meta) = std::fs::metadata(given)
            && !meta.is_file()
        {
            bail!(
                "{}: exists and is not a regular file (a folder, device or pipe); refusing to replace it",
                given.display()
            );
        }
        if let Some(k) = ins.iter().position(|p| p == o) {
            bail!(
                "output {} is the input {}: refusing to replace an input",
                given.display(),
                inputs[k].display()
            );
        }
        if let Some(k) = outs[..i].iter().position(|p| p == o) {
            bail!(
                "outputs {} and {} are the same file",
                outputs[k].display(),
                given.display()
            );
        }
    }
    Ok(())
}

/// The files `bake` and `export` write into folder `dir` under stem `name`, after
/// checking that `dir`, where it exists, is a folder.
pub(crate) fn volume_files(dir: &Path, name: &str) -> Result<Vec<PathBuf>> {
    if let Ok(meta) = std::fs::metadata(dir)
        && !meta.is_dir()
    {
        bail!(
            "{}: the output must be a folder, and this exists as something else",
            dir.display()
        );
    }
    Ok(["dds", "ktx2", "json"]
        .iter()
        .map(|e| dir.join(format!("{name}.{e}")))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_file_by_another_spelling_is_refused() {
        let dir = std::env::temp_dir().join(format!("lightgrid-paths-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let input = dir.join("in.lgrid");
        std::fs::write(&input, b"x").unwrap();
        let other = dir.join("sub/../in.lgrid");
        let e = check(&[&input], &[&other]).unwrap_err().to_string();
        assert!(e.contains("is the input"), "{e}");
        let (a, b) = (dir.join("out.png"), dir.join("sub/../out.png"));
        let e = check(&[&input], &[&a, &b]).unwrap_err().to_string();
        assert!(e.contains("the same file"), "{e}");
        let e = check(&[&input], &[&dir.join("sub")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a regular file"), "{e}");
        // Distinct new files and an existing regular output are fine.
        assert!(check(&[&input], &[&a, &dir.join("out.lgrid")]).is_ok());
        assert!(check(&[&a], &[&input]).is_ok());
        assert!(volume_files(&input, "v").is_err());
        assert_eq!(volume_files(&dir, "v").unwrap().len(), 3);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
