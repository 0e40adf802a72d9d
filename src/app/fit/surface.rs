//! The surface method of `fit`: the data alone (the plain carrier method), or the data with
//! off-surface constraints from estimated and oriented normals ([`crate::surface`]), which enter
//! the dense and the compactly supported systems as further centres.

use super::Run;
use crate::app::stages::{Stage, Stages};
use crate::cli::Surface;
use crate::error::Result;
use crate::par::{agree, Comm};
use crate::spline::hygiene::Prepared;
use crate::surface::{self, neighbourhoods, off_points, off_values};

/// Fewest points for which `--surface auto` adds off-surface constraints.
pub const AUTO_MIN_POINTS: usize = 50;

/// What the off-surface step did, for the report.
#[derive(Debug, Clone)]
pub struct SurfaceSummary {
    pub off_points: usize,
    pub dropped: usize,
    /// Smallest and largest delta in the caller's units.
    pub delta: (f64, f64),
    pub components: usize,
    pub patches: usize,
    pub flipped: usize,
    pub dense_dipole: bool,
}

/// The method `surface` resolves to for `n` points (true: off-surface constraints).
pub fn with_off_surface(surface: Surface, n: usize) -> bool {
    match surface {
        Surface::Carrier => false,
        Surface::OffSurface => true,
        Surface::Auto => n >= AUTO_MIN_POINTS,
    }
}

/// The name of the surface method in the report.
pub fn name(off: bool) -> &'static str {
    if off {
        "offsurface"
    } else {
        "carrier"
    }
}

/// `prep` with the off-surface points appended to its centres and values (its data points are
/// left as they are) and what was done. Collective.
pub fn constrain(run: &Run<'_>, prep: &Prepared, stages: &mut Stages) -> Result<(Prepared, SurfaceSummary)> {
    let comm: &dyn Comm = run.comm;
    let hoods = stages.time(Stage::Normals, || agree(comm, neighbourhoods(&prep.centres)))?;
    let (orientation, off) = stages.time(Stage::Orient, || -> Result<_> {
        let o = surface::oriented(comm, &prep.centres, &hoods)?;
        let off = off_points(&prep.centres, &o.normals, &hoods.tree, run.args.off_points);
        Ok((o, off))
    })?;
    let values = off_values(&off, &prep.points, &prep.carrier, &prep.norm);
    let scale = prep.norm.scale;
    let delta =
        off.delta.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| (lo.min(d * scale), hi.max(d * scale)));
    let summary = SurfaceSummary {
        off_points: off.side.len(),
        dropped: off.dropped,
        delta: if off.delta.is_empty() { (0.0, 0.0) } else { delta },
        components: orientation.components,
        patches: orientation.patches,
        flipped: orientation.flipped,
        dense_dipole: orientation.dense_dipole,
    };
    let mut out = prep.clone();
    out.centres.extend_from_slice(&off.centres);
    out.values.extend_from_slice(&values);
    Ok((out, summary))
}
