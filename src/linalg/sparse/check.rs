//! Validation of a [`SymCsr`] handed to a serial factorisation, so that a malformed matrix (from
//! a bug in assembly or a distributed matrix passed by mistake) is reported as an error instead of
//! an index panic deep inside a factorisation.

use super::SymCsr;
use crate::error::{Error, Result};

/// Checks that `a` is a whole matrix held on this process (rows 0..n in order), that its row
/// pointers are consistent, that every row's columns are strictly increasing and at most the row
/// (the lower triangle), and that every value is finite. `who` names the caller in messages.
pub(super) fn check_serial(a: &SymCsr, who: &str) -> Result<()> {
    let n = a.n;
    let bad = |what: String| Err(Error::Numerical(format!("{who}: malformed sparse matrix: {what}")));
    if a.rows.len() != n || a.rows.iter().enumerate().any(|(l, &g)| l != g) {
        return Err(Error::Usage(format!(
            "{who} needs the whole matrix on one process in row order; it holds {} of {n} rows",
            a.rows.len()
        )));
    }
    if a.row_ptr.len() != n + 1 || a.row_ptr[0] != 0 {
        return bad(format!(
            "{} row pointers for {n} rows, the first {:?}",
            a.row_ptr.len(),
            a.row_ptr.first()
        ));
    }
    if a.row_ptr[n] != a.cols.len() || a.cols.len() != a.vals.len() {
        return bad(format!(
            "row pointers end at {}, with {} column indices and {} values",
            a.row_ptr[n],
            a.cols.len(),
            a.vals.len()
        ));
    }
    for i in 0..n {
        let (lo, hi) = (a.row_ptr[i], a.row_ptr[i + 1]);
        if lo > hi {
            return bad(format!("row pointers decrease at row {i}"));
        }
        let cols = &a.cols[lo..hi];
        if cols.windows(2).any(|w| w[0] >= w[1]) {
            return bad(format!("the columns of row {i} are not strictly increasing"));
        }
        if let Some(&last) = cols.last() {
            if last > i {
                return bad(format!("row {i} has column {last}, above the diagonal"));
            }
        }
        if let Some(k) = a.vals[lo..hi].iter().position(|v| !v.is_finite()) {
            return bad(format!("entry ({i}, {}) is {}", cols[k], a.vals[lo + k]));
        }
    }
    Ok(())
}

/// Checks that `perm` (`perm[new] = old`) is a permutation of 0..n.
pub(super) fn check_permutation(perm: &[usize], n: usize, who: &str) -> Result<()> {
    if perm.len() != n {
        return Err(Error::Usage(format!("{who}: a permutation of {} entries for {n} rows", perm.len())));
    }
    let mut seen = vec![false; n];
    for (new, &old) in perm.iter().enumerate() {
        if old >= n || std::mem::replace(&mut seen[old], true) {
            return Err(Error::Usage(format!(
                "{who}: not a permutation of 0..{n}: entry {new} is {old} (out of range or repeated)"
            )));
        }
    }
    Ok(())
}

/// Checks that `rhs` holds `nrhs` right-hand sides of length `n` (column-major).
pub(super) fn check_rhs(rhs: &[f64], n: usize, nrhs: usize, who: &str) -> Result<()> {
    if rhs.len() != n.saturating_mul(nrhs) {
        return Err(Error::Usage(format!(
            "{who}: {} values for {nrhs} right-hand sides of order {n}",
            rhs.len()
        )));
    }
    Ok(())
}
