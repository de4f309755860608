//! Subcommands of the `altrep` binary. Each subcommand lives in its own file with a
//! `clap::Args` struct and a `run` function; `src/main.rs` only dispatches.

pub mod capture;
pub mod cylinder;
pub mod demo;
pub mod ellipsoid_bench;
pub mod fit_bench;
pub mod parallax;
pub mod precompute;
pub mod pyramid;
pub mod pyramid_bench;
pub mod report;
pub mod slices;
pub mod sphere;

/// Error type of the command-line layer: a message for the user, already formatted.
pub type CliResult = Result<(), Box<dyn std::error::Error + Send + Sync>>;

/// Whether the folder `out`, which a command replaces whole, may be replaced: absent, empty, or a
/// folder the command wrote — holding its description `description`, whose `listing` (the
/// entries it wrote, itself included) covers every entry. A symbolic link, a file, a folder
/// without the description and an entry it does not list are refused, naming the path: the
/// user's files are never replaced. Cost: one read of the folder and of the description.
pub fn check_replaceable(
    out: &std::path::Path,
    command: &str,
    description: &str,
    listing: impl Fn(&std::path::Path) -> Option<std::collections::BTreeSet<String>>,
) -> Result<(), String> {
    let refuse = |path: &std::path::Path, why: &str| {
        format!(
            "{}: {why}; {command} replaces only a folder it wrote: move it aside or choose \
             another folder",
            path.display()
        )
    };
    let meta = match std::fs::symlink_metadata(out) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(format!("{}: {e}", out.display())),
    };
    if meta.file_type().is_symlink() {
        return Err(refuse(out, "is a symbolic link"));
    }
    if !meta.is_dir() {
        return Err(refuse(out, "is a file"));
    }
    let entries: Vec<String> = std::fs::read_dir(out)
        .map_err(|e| format!("{}: {e}", out.display()))?
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if entries.is_empty() {
        return Ok(());
    }
    let Some(listed) = listing(out) else {
        return Err(refuse(out, &format!("holds no {description} of altrep's")));
    };
    match entries.iter().find(|e| !listed.contains(*e)) {
        Some(extra) => Err(refuse(
            &out.join(extra),
            &format!("is not among the files its {description} lists"),
        )),
        None => Ok(()),
    }
}

/// Writes `value` as pretty JSON to the file `path` a user named (`--json`): to a temporary name
/// beside it, then renamed over it, so the file is never half written. Errors name the path.
pub fn write_json(path: &std::path::Path, value: &impl serde::Serialize) -> CliResult {
    let text = serde_json::to_string_pretty(value)?;
    crate::asset::write_atomic(path, text.as_bytes())
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

/// The one parser of three sizes written `AxBxC` (grid cells, sample counts), for every
/// subcommand's `value_parser`. Rule: exactly three integers ≥ 1, separated by `x`, `X` or `×`,
/// spaces around each integer allowed (`15x8x16`, `15×8×16`, `15 x 8 x 16`).
pub fn parse_sizes(s: &str) -> Result<[usize; 3], String> {
    let bad =
        || format!("expected three positive integers separated by 'x', like 15x8x16; got '{s}'");
    let parts: Vec<&str> = s.split(['x', 'X', '×']).collect();
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut sizes = [0; 3];
    for (n, p) in sizes.iter_mut().zip(&parts) {
        *n = p.trim().parse::<usize>().map_err(|_| bad())?;
        if *n == 0 {
            return Err(bad());
        }
    }
    Ok(sizes)
}

/// [`parse_sizes`], each size also at most `MAX` (for options whose cost grows with the size).
pub fn parse_sizes_upto<const MAX: usize>(s: &str) -> Result<[usize; 3], String> {
    let sizes = parse_sizes(s)?;
    if sizes.iter().any(|&n| n > MAX) {
        return Err(format!("sizes must be in 1..={MAX}; got '{s}'"));
    }
    Ok(sizes)
}

#[cfg(test)]
mod tests {
    use super::{parse_sizes, parse_sizes_upto};

    #[test]
    fn sizes_parse_with_every_separator() {
        assert_eq!(parse_sizes("15x8x16"), Ok([15, 8, 16]));
        assert_eq!(parse_sizes("8×4×8"), Ok([8, 4, 8]));
        assert_eq!(parse_sizes("128X64X256"), Ok([128, 64, 256]));
        assert_eq!(parse_sizes(" 15 x 8 x 16 "), Ok([15, 8, 16]));
        assert_eq!(parse_sizes_upto::<256>("256x1x2"), Ok([256, 1, 2]));
    }

    #[test]
    fn bad_sizes_are_errors_naming_the_input() {
        for bad in [
            "",
            "15",
            "15x8",
            "15x8x16x2",
            "0x8x16",
            "15x0x16",
            "ax8x16",
            "15x-8x16",
            "15x8.5x16",
            "15xx8",
            "15,8,16",
            "x8x16",
            "99999999999999999999999x1x1",
        ] {
            let e = parse_sizes(bad).expect_err(bad);
            assert!(e.contains(&format!("'{bad}'")), "{e}");
        }
        let e = parse_sizes_upto::<256>("257x8x16").unwrap_err();
        assert!(e.contains("1..=256") && e.contains("257x8x16"), "{e}");
    }
}
