//! MatrixMarket reading and writing, so external solvers (SciPy, Julia, MATLAB) can be run on
//! the same systems.
//!
//! Written: sparse matrices as `coordinate real general` (1-based indices, one entry per line),
//! vectors as `array real general` (`n 1`). Values are printed with Rust's shortest round-trip
//! exponent form (`{:e}`), so a write/read cycle is exact.
//!
//! Read: `coordinate` with `real`, `integer` or `pattern` values and `general`, `symmetric` or
//! `skew-symmetric` storage (duplicates are summed); `array` (column-major) for vectors and
//! dense `n × 1` / `1 × n` data. `complex` and `hermitian` are rejected with
//! [`SolverError::MatrixMarket`]. (We do not use `sprs::io`: it prints values without an
//! exponent, so `1e-300` takes 300 characters, and its reader loops forever on a file that ends
//! after the header.)

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;

use sprs::{CsMat, CsMatViewI, SpIndex, TriMat};

use crate::error::SolverError;

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SolverError + '_ {
    move |source| SolverError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Writes a sparse matrix (CSR or CSC) as `coordinate real general`. Cost: O(nnz) lines.
pub fn write_matrix_market<I: SpIndex, Iptr: SpIndex>(
    path: impl AsRef<Path>,
    a: CsMatViewI<'_, f64, I, Iptr>,
) -> Result<(), SolverError> {
    let path = path.as_ref();
    let f = File::create(path).map_err(io_err(path))?;
    let mut w = BufWriter::new(f);
    write_matrix_market_to(&mut w, a)
        .and_then(|_| w.flush())
        .map_err(io_err(path))
}

/// [`write_matrix_market`] to any writer.
pub fn write_matrix_market_to<I: SpIndex, Iptr: SpIndex>(
    w: &mut dyn Write,
    a: CsMatViewI<'_, f64, I, Iptr>,
) -> std::io::Result<()> {
    writeln!(w, "%%MatrixMarket matrix coordinate real general")?;
    writeln!(w, "% written by altrep-solvers")?;
    writeln!(w, "{} {} {}", a.rows(), a.cols(), a.nnz())?;
    for (v, (i, j)) in a.iter() {
        writeln!(w, "{} {} {:e}", i.index() + 1, j.index() + 1, v)?;
    }
    Ok(())
}

/// Writes a vector as `array real general` of shape `n × 1`. Cost: O(n) lines.
pub fn write_vector(path: impl AsRef<Path>, v: &[f64]) -> Result<(), SolverError> {
    let path = path.as_ref();
    let f = File::create(path).map_err(io_err(path))?;
    let mut w = BufWriter::new(f);
    write_vector_to(&mut w, v)
        .and_then(|_| w.flush())
        .map_err(io_err(path))
}

/// [`write_vector`] to any writer.
pub fn write_vector_to(w: &mut dyn Write, v: &[f64]) -> std::io::Result<()> {
    writeln!(w, "%%MatrixMarket matrix array real general")?;
    writeln!(w, "% written by altrep-solvers")?;
    writeln!(w, "{} 1", v.len())?;
    for x in v {
        writeln!(w, "{x:e}")?;
    }
    Ok(())
}

/// What a MatrixMarket file held.
#[derive(Debug, Clone)]
pub enum MatrixMarketData {
    /// A `coordinate` file, as a CSR matrix (duplicates summed, symmetric storage expanded).
    Sparse(CsMat<f64>),
    /// An `array` file: `rows × cols` values in column-major order.
    Dense {
        /// Rows.
        rows: usize,
        /// Columns.
        cols: usize,
        /// Values, column-major.
        values: Vec<f64>,
    },
}

/// Reads a sparse matrix (a `coordinate` file) as CSR. Errors on an `array` file.
pub fn read_matrix_market(path: impl AsRef<Path>) -> Result<CsMat<f64>, SolverError> {
    let path = path.as_ref();
    match read_any(path)? {
        MatrixMarketData::Sparse(a) => Ok(a),
        MatrixMarketData::Dense { .. } => Err(mm_err(
            path,
            1,
            "expected a coordinate (sparse) file, found array",
        )),
    }
}

/// Reads a vector: an `array` file of shape `n × 1` or `1 × n`, or a `coordinate` file of such
/// a shape (missing entries are 0).
pub fn read_vector(path: impl AsRef<Path>) -> Result<Vec<f64>, SolverError> {
    let path = path.as_ref();
    match read_any(path)? {
        MatrixMarketData::Dense { rows, cols, values } if rows == 1 || cols == 1 => Ok(values),
        MatrixMarketData::Sparse(a) if a.rows() == 1 || a.cols() == 1 => {
            let mut v = vec![0.0; a.rows() * a.cols()];
            for (x, (i, j)) in a.iter() {
                v[i.max(j)] += x;
            }
            Ok(v)
        }
        _ => Err(mm_err(path, 1, "expected an n×1 or 1×n matrix")),
    }
}

fn read_any(path: &Path) -> Result<MatrixMarketData, SolverError> {
    let f = File::open(path).map_err(io_err(path))?;
    read_matrix_market_from(BufReader::new(f), &path.display().to_string())
}

fn mm_err(path: &Path, line: usize, reason: &str) -> SolverError {
    SolverError::MatrixMarket {
        path: path.display().to_string(),
        line,
        reason: reason.to_string(),
    }
}

/// Reads any supported MatrixMarket content from a reader; `name` labels errors.
pub fn read_matrix_market_from(
    reader: impl BufRead,
    name: &str,
) -> Result<MatrixMarketData, SolverError> {
    let err = |line: usize, reason: String| SolverError::MatrixMarket {
        path: name.to_string(),
        line,
        reason,
    };
    let mut lines = reader.lines().enumerate().map(|(i, l)| (i + 1, l));
    let mut next_line = |what: &str| -> Result<Option<(usize, String)>, SolverError> {
        match lines.next() {
            None => Ok(None),
            Some((n, Ok(s))) => Ok(Some((n, s))),
            Some((n, Err(e))) => Err(err(n, format!("cannot read {what}: {e}"))),
        }
    };
    let (_, header) = next_line("header")?.ok_or_else(|| err(1, "empty file".into()))?;
    let words: Vec<String> = header
        .split_whitespace()
        .map(|w| w.to_ascii_lowercase())
        .collect();
    if words.len() != 5 || words[0] != "%%matrixmarket" || words[1] != "matrix" {
        return Err(err(1, format!("bad header {header:?}")));
    }
    let (format, field, symmetry) = (words[2].as_str(), words[3].as_str(), words[4].as_str());
    if !matches!(field, "real" | "integer" | "pattern" | "double") {
        return Err(err(1, format!("unsupported field {field:?}")));
    }
    let sym = match symmetry {
        "general" => 0,
        "symmetric" => 1,
        "skew-symmetric" => -1,
        _ => return Err(err(1, format!("unsupported symmetry {symmetry:?}"))),
    };
    // Size line: the first line that is neither a comment nor blank.
    let (size_no, size_line) = loop {
        match next_line("size line")? {
            None => return Err(err(1, "missing size line".into())),
            Some((_, s)) if s.trim().is_empty() || s.starts_with('%') => continue,
            Some(x) => break x,
        }
    };
    let sizes: Vec<usize> = size_line
        .split_whitespace()
        .map(|t| t.parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|e| err(size_no, format!("bad size line: {e}")))?;
    let parse_f = |n: usize, t: Option<&str>| -> Result<f64, SolverError> {
        let t = t.ok_or_else(|| err(n, "missing value".into()))?;
        t.parse::<f64>()
            .map_err(|e| err(n, format!("bad value {t:?}: {e}")))
    };
    match format {
        "coordinate" => {
            let [rows, cols, nnz] = sizes[..] else {
                return Err(err(
                    size_no,
                    "coordinate size line must be `rows cols nnz`".into(),
                ));
            };
            let mut t = TriMat::with_capacity((rows, cols), if sym == 0 { nnz } else { 2 * nnz });
            let mut seen = 0;
            while seen < nnz {
                let Some((n, s)) = next_line("entry")? else {
                    return Err(err(
                        size_no,
                        format!("file ends after {seen} of {nnz} entries"),
                    ));
                };
                if s.trim().is_empty() || s.starts_with('%') {
                    continue;
                }
                let mut tok = s.split_whitespace();
                let mut idx = |what: &str, max: usize| -> Result<usize, SolverError> {
                    let v: usize = tok
                        .next()
                        .and_then(|t| t.parse().ok())
                        .ok_or_else(|| err(n, format!("bad {what} index")))?;
                    if v == 0 || v > max {
                        return Err(err(n, format!("{what} index {v} outside 1..={max}")));
                    }
                    Ok(v - 1)
                };
                let i = idx("row", rows)?;
                let j = idx("column", cols)?;
                let v = if field == "pattern" {
                    1.0
                } else {
                    parse_f(n, tok.next())?
                };
                t.add_triplet(i, j, v);
                if sym != 0 && i != j {
                    if j >= rows || i >= cols {
                        return Err(err(n, "symmetric storage of a non-square matrix".into()));
                    }
                    t.add_triplet(j, i, sym as f64 * v);
                }
                seen += 1;
            }
            Ok(MatrixMarketData::Sparse(t.to_csr()))
        }
        "array" => {
            let [rows, cols] = sizes[..] else {
                return Err(err(size_no, "array size line must be `rows cols`".into()));
            };
            if sym != 0 && rows != cols {
                return Err(err(size_no, "symmetric array must be square".into()));
            }
            let mut values = vec![0.0; rows * cols];
            // General: all entries column-major; symmetric: the lower triangle column-major.
            let slots: Vec<(usize, usize)> = (0..cols)
                .flat_map(|j| (0..rows).map(move |i| (i, j)))
                .filter(|&(i, j)| sym == 0 || i >= j)
                .collect();
            let mut k = 0;
            while k < slots.len() {
                let Some((n, s)) = next_line("value")? else {
                    return Err(err(
                        size_no,
                        format!("file ends after {k} of {} values", slots.len()),
                    ));
                };
                if s.trim().is_empty() || s.starts_with('%') {
                    continue;
                }
                let v = parse_f(n, s.split_whitespace().next())?;
                let (i, j) = slots[k];
                values[i + rows * j] = v;
                if sym != 0 && i != j {
                    values[j + rows * i] = sym as f64 * v;
                }
                k += 1;
            }
            Ok(MatrixMarketData::Dense { rows, cols, values })
        }
        _ => Err(err(1, format!("unsupported format {format:?}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_exact() {
        let mut t = TriMat::new((3, 4));
        t.add_triplet(0, 0, 1.0 / 3.0);
        t.add_triplet(2, 3, -1e-300);
        t.add_triplet(1, 2, 6.02e23);
        let a: CsMat<f64> = t.to_csr();
        let mut buf = Vec::new();
        write_matrix_market_to(&mut buf, a.view()).unwrap();
        let MatrixMarketData::Sparse(b) = read_matrix_market_from(&buf[..], "mem").unwrap() else {
            panic!("expected sparse");
        };
        assert_eq!(a, b);
        let v = vec![0.1, -2.5e-17, 3.0];
        let mut buf = Vec::new();
        write_vector_to(&mut buf, &v).unwrap();
        let MatrixMarketData::Dense { values, .. } =
            read_matrix_market_from(&buf[..], "m").unwrap()
        else {
            panic!("expected dense");
        };
        assert_eq!(values, v);
    }

    #[test]
    fn symmetric_storage_is_expanded() {
        let text = "%%MatrixMarket matrix coordinate real symmetric\n% c\n2 2 2\n1 1 4\n2 1 -1\n";
        let MatrixMarketData::Sparse(a) = read_matrix_market_from(text.as_bytes(), "m").unwrap()
        else {
            panic!("expected sparse");
        };
        assert_eq!(a.get(0, 1), Some(&-1.0));
        assert_eq!(a.get(1, 0), Some(&-1.0));
    }

    #[test]
    fn malformed_files_give_typed_errors() {
        for text in [
            "",
            "%%MatrixMarket matrix coordinate real general\n",
            "%%MatrixMarket matrix coordinate complex general\n1 1 1\n1 1 1 0\n",
            "%%MatrixMarket matrix coordinate real general\n2 2 2\n1 1 1\n",
            "%%MatrixMarket matrix coordinate real general\n2 2 1\n3 1 1\n",
            "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 abc\n",
        ] {
            assert!(
                matches!(
                    read_matrix_market_from(text.as_bytes(), "m"),
                    Err(SolverError::MatrixMarket { .. })
                ),
                "{text:?}"
            );
        }
    }
}
