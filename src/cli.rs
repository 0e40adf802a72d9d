//! The command line: clap definitions that turn every argument into its typed value (solver,
//! kernel, carrier, grid, box, plane family, ...) while parsing, so a mistyped option is reported
//! with usage before MPI starts and the commands in `app` never see a string to interpret.

use std::path::PathBuf;

use clap::parser::ValueSource;
use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};

use crate::app::progress;
use crate::contour::planes::PlaneFamily;
use crate::contour::{Interp, Orient, SectionCarrier};
use crate::error::{Error, Result};
use crate::frep::raycast::{Axis, Colouring};
use crate::frep::Syntax;
use crate::grid::{parse_bounds, GridSize, Margin};
use crate::linalg::dist::{Layout, Precision, SolverKind};
use crate::linalg::gemm::Engine;
use crate::spline::{Carrier, Kernel};
use crate::surface::offsurface::Deal;

/// The program's version and the commit it was built from (`unknown` outside a git work tree,
/// `+modified` where its sources differ from that commit), as `--version`, the timings and the
/// models' provenance give it.
pub const VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), " (", env!("VOLSPLINE_REVISION"), ")");

/// volspline: reconstruct solids from scattered surface points as a volume spline f(x,y,z) with
/// f >= 0 inside (Savchenko et al. 1995), on any number of MPI ranks.
///
/// Run under `mpirun -n P volspline ...` (or as one process without mpirun). The rows of the dense
/// system and the evaluation grid are split across ranks; each rank uses threads for its share.
#[derive(Debug, Parser)]
#[command(name = "volspline", version = VERSION, about, long_about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Fit a volume spline to scattered points; write PREFIX.model.h5, PREFIX.hdf (VTKHDF volume of
    /// f for ParaView) and PREFIX.ply (the surface f = 0).
    Fit(FitArgs),
    /// Evaluate a saved model, or an FRep expression over models and carriers (README.md,
    /// "Expressions"), on a grid without solving again; write PREFIX.hdf and PREFIX.ply.
    Eval(EvalArgs),
    /// Metamorphosis of solid A into solid B (models or expressions): K frames of
    /// (1-t) fA + t fB, each PREFIX_NNN.hdf and PREFIX_NNN.ply, and PREFIX.hdf.series, the time
    /// series ParaView opens as one animated dataset.
    Morph(MorphArgs),
    /// Reconstruct a solid from planar cross-sections (a contour file, see README.md): one 2D
    /// spline per slice, interpolated between slices; write PREFIX.model.h5, PREFIX.hdf, PREFIX.ply.
    Contours(ContoursArgs),
    /// Cut a triangle mesh (.obj/.ply/.stl) by a family of planes and write the contour file.
    Slice(SliceArgs),
    /// Ray-cast a solid into a PNG picture (shaded from the analytic gradient, or coloured by
    /// mean curvature), pixel rows split over ranks.
    Render(RenderArgs),
}

#[derive(Debug, Args)]
pub struct FitArgs {
    /// Points: .obj (vertices), .ply (ascii or binary; vertex x, y, z), .stl (ascii or binary; the facets'
    /// corners, shared ones once), .pcd (ascii, binary or binary_compressed; fields x, y, z), .las (LAS
    /// 1.0-1.4, scaled and offset), .e57 (every scan, placed by its pose), .xyz/.txt/.csv (x y z per
    /// line).
    pub input: PathBuf,
    /// Output prefix: writes PREFIX.model.h5, PREFIX.hdf, PREFIX.ply.
    #[arg(long, value_name = "PREFIX")]
    pub out: PathBuf,
    /// Carrier solid: auto (ellipsoid(0.3) for the off-surface fit, ball for the plain carrier
    /// method), ball (fitted to the data), ball:cx,cy,cz,r, ellipsoid (fitted to the data: the
    /// principal axes and extents of the points), ellipsoid(S) (the same with the spread of its
    /// semi-axes scaled by S in 0..1 on a log scale: 0 is a ball), ellipsoid:cx,cy,cz,a,b,c
    /// (along the coordinate axes; nine more numbers give the unit axes one after the other), or
    /// union(A,B) / intersection(A,B) / difference(A,B) of carriers (R-functions).
    #[arg(long, default_value = "auto", value_name = "SPEC", value_parser = fit_carrier)]
    pub carrier: FitCarrier,
    /// How the spline is built: dense (a global Green's function, the dense row-cyclic solvers),
    /// csrbf (a compactly supported Wendland function: an octree, a sparse Cholesky, MUMPS across
    /// ranks) or auto (dense while its matrix fits in memory and its solve should take under
    /// 15 s, csrbf above).
    #[arg(long, default_value = "auto", value_name = "auto|dense|csrbf", value_parser = method)]
    pub method: Method,
    /// Radial function: r (m = 2, biharmonic) or r3 (m = 3, triharmonic) for dense;
    /// wendland0, wendland2, wendland4 (C0, C2, C4 Wendland functions of compact support) for
    /// csrbf; auto: r for dense, wendland2 for csrbf.
    #[arg(long, default_value = "auto", value_name = "auto|r|r3|wendland0|wendland2|wendland4", value_parser = kernel_choice)]
    pub kernel: KernelChoice,
    /// Support radius of a Wendland kernel, in the internal coordinates where the data's bounding
    /// box is centred with diagonal 2 (default: from the point spacing, so that each point has
    /// about 30 neighbours).
    #[arg(long, allow_hyphen_values = true, value_name = "R", value_parser = support)]
    pub support: Option<f64>,
    /// Points per octree leaf for csrbf.
    #[arg(long, allow_negative_numbers = true, default_value = "10", value_name = "K", value_parser = leaf)]
    pub leaf: usize,
    /// Sparse solver of csrbf: auto (cholesky on one rank, mumps on several), cholesky (sparse
    /// supernodal Cholesky with a fill-reducing ordering, one rank), envelope (envelope Cholesky
    /// after the octree ordering, one rank) or mumps (distributed multifrontal Cholesky).
    #[arg(long, default_value = "auto", value_name = "auto|cholesky|envelope|mumps", value_parser = sparse_solver)]
    pub sparse_solver: SparseSolver,
    /// Distributed dense solver: auto (the fastest for the size: householder below 100 rows,
    /// cholesky above), cholesky (projected Cholesky of the definite block, falls back to lu with a
    /// message when a pivot is not positive), householder (QR) or lu (partial pivoting).
    #[arg(long, default_value = "auto", value_name = "auto|cholesky|householder|lu", value_parser = with(SolverKind::parse))]
    pub solver: SolverKind,
    /// Working precision of the dense solve: f64, or mixed (factored in f32: the projected
    /// Cholesky where --solver gives cholesky for the size, LU otherwise; refined in f64 to the
    /// residual of an f64 solve, by classical refinement and then GMRES-IR; when the f32
    /// factorisation or the refinement fails, the --solver solve in f64, with a message).
    #[arg(long, default_value = "f64", value_name = "f64|mixed", value_parser = with(Precision::parse))]
    pub precision: Precision,
    /// Library of the dense solvers' local matrix products (almost all their flops): auto (the
    /// machine's BLAS behind libblas.so.3 where it is an optimised one: OpenBLAS, MKL or BLIS;
    /// faer otherwise), blas (the loaded BLAS, whichever it is) or faer. The BLAS computes a
    /// rank's products when the rank runs one thread (as many ranks as cores, or --threads 1);
    /// with more threads a rank's products are faer's, threaded. On a 2-core AVX2 node OpenBLAS
    /// made the N+k = 8000 solves 17-28 % faster than faer's product.
    #[arg(long, default_value = "auto", value_name = "auto|blas|faer", value_parser = with(Engine::parse))]
    pub gemm: Engine,
    /// Panel (block) width of the distributed solvers (0: automatic, 192 for householder (128
    /// with faer's products), 192 for lu (with faer's products, 320 from 6000 rows), 256 for
    /// cholesky below 6000 rows and 384 from 6000; on a 2D grid the block size, 128).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0, value_name = "NB")]
    pub panel: usize,
    /// Look-ahead of the factorisations: on, off, or auto (the default). On the row-cyclic
    /// layout each panel's trailing update runs while the next panel's collectives are in flight
    /// (the LU's pivot searches, the Householder panel's all-reduces, the projected Cholesky's
    /// gathers); auto turns it on there for the projected Cholesky only (5-7 % faster on one
    /// node; LU no faster, Householder slower). On a 2D grid auto is on when the grid has more
    /// than one process column (the next panel's column factors it and broadcasts it during the
    /// trailing update), off with one.
    #[arg(long, default_value = "auto", value_name = "auto|on|off", value_parser = on_off_auto)]
    pub lookahead: LookAhead,
    /// Distribution of the dense system over the ranks: auto, row-cyclic (global row g on rank
    /// g mod p; every solver), 2d (blocks of --panel rows and columns on the
    /// squarest process grid, as ScaLAPACK deals them; every solver, in f64) or an explicit
    /// process grid PRxPC whose product is the rank count. On one 16-core node, 2d on 16 ranks
    /// (4x4) solved 1.2-2x faster than row-cyclic from N = 2000 on; on 4 and 8 ranks the two were
    /// within about 15 %. So auto takes 2d from 16 ranks on, where the squarest grid has at least
    /// 4 process rows and the system at least 2000 rows, and row-cyclic otherwise, and always for
    /// --precision mixed. An off-surface fit on a grid moves its first factor to the row-cyclic
    /// layout once, where its second fits border it instead of factoring anew.
    #[arg(long, default_value = "auto", value_name = "auto|row-cyclic|2d|PRxPC", value_parser = with(Layout::parse))]
    pub layout: Layout,
    /// Points closer than this fraction of the bounding-box diagonal are merged into one.
    #[arg(long, allow_hyphen_values = true, default_value = "1e-6", value_name = "F", value_parser = merge_tol)]
    pub merge_tol: f64,
    /// Isolated points (their 8th nearest neighbour more than 10 times the median such distance
    /// away: stray scanner returns, alone or in groups of up to 8; and groups apart from the rest
    /// by that distance holding at most 1 % of the points) are named and left out of the
    /// fit (on), or named in a warning and fitted (off). Kept, they stretch the carrier and the
    /// grid over empty space and the surface is pulled out to them.
    #[arg(long, default_value = "on", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub drop_isolated: bool,
    /// Do not write the picture PREFIX.png of the solid.
    #[arg(long)]
    pub no_preview: bool,
    /// What the spline is fitted to: auto (offsurface when there are enough points to estimate
    /// normals, carrier below), offsurface (normals estimated and oriented from the points, and
    /// constraints p +- delta n beside the surface added: clean solids from scans without
    /// normals) or carrier (the data alone, the plain carrier method of the paper).
    #[arg(long, default_value = "auto", value_name = "auto|offsurface|carrier", value_parser = surface)]
    pub surface: Surface,
    /// Off-surface points per data point for --surface offsurface: 2 (both sides of every point,
    /// 3N rows), 1 (one side), below 1 (one side on a subset; --off-deal says which). Points whose
    /// normals disagree with their 8 nearest neighbours' get --doubtful-share of it. The default
    /// 0.5 keeps the dense factorisation within 1.5^3 = 3.4 times the plain method's (about 2.5
    /// times for the usual share of doubtful normals).
    #[arg(long, allow_hyphen_values = true, default_value = "0.5", value_name = "F", value_parser = off_rate)]
    pub off_points: f64,
    /// The share of --off-points that a data point gets when its oriented normal disagrees
    /// (cosine 0.9 or less) with one of its 8 nearest neighbours' (thin parts, noise): 0 gives
    /// such points no off points, 1 treats every point alike. Where more than 70 % of the normals
    /// are doubtful (sparse or row-wise samples) the share rises linearly to 1 at 100 %.
    #[arg(long, allow_hyphen_values = true, default_value = "0.4", value_name = "S", value_parser = share)]
    pub doubtful_share: f64,
    /// Which data points get the off-surface points, and on which side: neighbours (dealt among
    /// each point's 8 nearest neighbours by draws from its coordinates: the same cloud in any
    /// order, on any number of ranks, gives the same solid, to rounding) or index (a stride
    /// through the input order, sides alternating: another order gives another solid). Both
    /// meet the surface benchmark's quality targets equally often on an arbitrary order of its
    /// clouds. Either way there are at most --off-points x N off points, the rows the memory
    /// checks allow for.
    #[arg(long, default_value = "neighbours", value_name = "neighbours|index", value_parser = off_deal)]
    pub off_deal: Deal,
    /// Smoothing lambda for noisy scans (0: the spline interpolates). The spline minimises
    /// sum_i (U(P_i) - r_i)^2 + lambda E(U) instead of interpolating, as scipy's RBFInterpolator
    /// does with `smoothing`: lambda is added to the diagonal of the kernel matrix, in the
    /// internal coordinates (the data's bounding box centred with diagonal 2), for every
    /// constraint point. Larger values pull the solid towards the carrier: with --surface carrier
    /// 0.3 halved the surface error of a sphere scanned with 2 % noise; with off-surface
    /// constraints no value from 1e-3 to 0.3 improved the scans of README.md (Smoothing).
    #[arg(long, allow_hyphen_values = true, default_value = "0", value_name = "LAMBDA", value_parser = smoothing)]
    pub smooth: f64,
    /// Also write PREFIX.trimmed.ply: the surface without the regions of triangles farther than F
    /// times the data's median spacing from every data point that reach twice as far somewhere,
    /// or stand that far off the plane of the nearest data somewhere with 15 % of their area at
    /// least half as far off it (F = 2 when no value is given). An open surface, as density
    /// trimming gives screened Poisson: it removes what no data supports (bulges, webs) and opens
    /// the holes of the scan, but not the small gaps of random sampling. The volume and
    /// PREFIX.ply stay the closed solid.
    #[arg(long, value_name = "F", num_args = 0..=1, default_missing_value = "2", value_parser = trim_factor)]
    pub trim: Option<f64>,
    /// Move every data point onto a quadric fitted to its 19 nearest neighbours on the same sheet
    /// (oriented normals within 60 degrees), by at most twice the noise the quadrics' misfit
    /// estimates, before the off-surface fit (auto, on or off); the spline then interpolates the
    /// moved points. auto does so where the misfit is noise rather than curvature: where the
    /// median misfit of quadrics through 19 neighbours is less than 1.38 times that through 9
    /// (noise is the same at both sizes, curvature grows with the neighbourhood). It took the
    /// bunny and the cow at 2000 points with noise of 0.5 % of the diagonal from 0.43-0.50 to
    /// 0.35-0.40 % mesh -> truth and made clean scans worse (README.md, Denoising). Only for the
    /// dense off-surface fit (auto stays off elsewhere).
    #[arg(long, default_value = "auto", value_name = "auto|on|off", value_parser = denoise_mode)]
    pub denoise: Denoise,
    /// The side vote: small patches of the oriented normals whose off-plane neighbours lie mostly
    /// on their outer side (the two sides of thin parts, legs and ears, seen in one
    /// neighbourhood; see src/surface/orient.rs) are turned. try (the default): the vote's turns
    /// are tried together as one turn after the blob search, by one solve with the kept factor,
    /// and kept where they leave fewer unsupported crossings (src/surface/turns.rs); on: turned
    /// in the orientation itself (it helped the cow at 4000 points and hurt it at 1000); off:
    /// never; both: the dense off-surface fit is made twice, without and with the vote in the
    /// orientation, and the one leaving fewer unsupported crossings kept (about 1.5 times the
    /// default's time). README.md, Choosing the side vote by the spline.
    #[arg(long, default_value = "try", value_name = "try|on|off|both", value_parser = side_vote_mode)]
    pub orient_side: SideVote,
    /// Turn whole patches of the estimated normals where that lowers the bending energy of the
    /// off-surface spline (on, or off), for up to 6000 rows (see src/surface/energy.rs).
    #[arg(long, default_value = "off", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub orient_energy: bool,
    /// After the first fit, follow rays inward and outward from every data point and turn the
    /// small patches of normals whose inward rays leave the solid far from every data point and
    /// whose outward rays meet it again (on, or off): a patch turned inward makes a shell of
    /// false solid around a thin part; the fit is then made a second time (see
    /// src/surface/rays.rs).
    #[arg(long, default_value = "on", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub orient_rays: bool,
    /// Where the first fit's solid spills far beyond the data (positive on the faces of the
    /// data's box grown by a quarter of its longest side: the two sides of a part thinner than
    /// the spacing of the points oriented alike), turn every normal away from the plane of its
    /// point's neighbourhood, fit again and keep that fit when it spills at most a fifth as much
    /// (on, or off; see src/surface/sheets.rs). It costs a second dense fit of the same size, only
    /// where the first spilled.
    #[arg(long, default_value = "on", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub orient_by_side: bool,
    /// Where the blob search after the first fit pins different nodes with its wide clearance
    /// (5 % of the diagonal) and a narrow one (2 median spacings of the data), make both second
    /// fits and keep the one with less surface far from every data point, not counting surface
    /// in the mouth of a hole (on, or off: the wide clearance alone, and no second round of the
    /// search where the cap left most spurious nodes unpinned). With the dense projected
    /// Cholesky both second fits border the first fit's factor, so the choice costs little
    /// (see src/surface/choice.rs).
    #[arg(long, default_value = "on", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub blob_choice: bool,
    /// Where the blob search's pins took the solid from data points the first fit had it at (a
    /// part thinner than the lattice, such as a leg sampled by three points, sinks below zero
    /// under the pins' far reach), constrain the first fit's value at the node of each such
    /// point's lattice cell where it was largest, if the data enclose that node (winding number
    /// at least 1/2) where there are at least 4 such nodes, and, for each such point with no
    /// data point with solid within 5 % of the box diagonal (a part sampled at its end alone,
    /// lost whole), at the nodes of the shortest way through the first fit's solid from it to
    /// the solid kept; keep that fit when fewer data points are left without solid (on, or off).
    /// One more fit, bordering the first fit's factor, where solid was lost (see
    /// src/surface/blobs.rs, "Solid given back" and "Along the first fit's solid").
    #[arg(long, default_value = "on", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub restore_solid: bool,
    /// Last, where the dense fit kept its factor, try turning the small patches of normals
    /// nearest to the surface no data supports (on, or off), at most 6 (past the third only
    /// patches of 4 points or more), and keep a turn that
    /// removes at least 5 % of that surface: a patch turned on a sheet thinner than the sampling
    /// (an ear) holds up a bulge beside it that the ray test cannot see. Then at most 3 groups
    /// of points with another sheet of data in front of them (one side of a thin part turned),
    /// kept where the turn clears that surface in open space. A try changes only values, so it is solved with the kept fit's own factor (two triangular solves; below 1000
    /// points a fit that keeps none, by a solver the user chose, is made afresh) and only the
    /// lattice around the patch is sampled again; a large system solved without the projected
    /// Cholesky skips this step (see src/surface/turns.rs).
    #[arg(long, default_value = "on", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub orient_turns: bool,
    /// Last, where the turns could run, give the data points nearest to the surface no data
    /// supports that is left in open space (the data's winding number below 0.1), and that have
    /// no off point, an outside off point each (at the median delta, halved at most 3 times until
    /// it is nearest to its own point), and keep that fit when it removes at least 5 % of the
    /// unsupported surface (on, or off): a bulge beside a thin part held by points without off
    /// points goes. One more fit, bordering the kept fit's factor (see src/surface/outside.rs).
    #[arg(long, default_value = "on", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub outside_points: bool,
    /// Then, where the turns could run, give the data points on a rim (their 15 nearest
    /// neighbours leave a gap of 140 degrees or more around them, and none has a normal more
    /// than a right angle from theirs, as at the tip of a thin part) nearest to at least 3
    /// crossings of the surface no data supports in the mouths of holes (the data's winding
    /// number between 0.4 and 0.6) an off point on each side where they have none, and keep
    /// that fit (on, or off): held on both sides, the rim of a scan's hole keeps the slope of
    /// the surface around it, and the cap over the hole sags less into the solid (a cow at 1000
    /// points with a hole: truth -> mesh 1.25 -> 0.99 % of the diagonal). One more fit,
    /// bordering the kept fit's factor (see src/surface/outside.rs).
    #[arg(long, default_value = "on", value_name = "on|off", value_parser = on_off, action = clap::ArgAction::Set)]
    pub mouth_points: bool,
    /// How steeply the targets of the off points at the rims of holes (--mouth-points) rise, as
    /// a multiple of the other off points' slope (the carrier's at the point): above 1 the cap
    /// over a hole follows the surface around it further instead of sagging toward the carrier.
    /// On the 240 holed sets of the surface benchmark 1, 2 and 3 (the default) met every quality
    /// target on 107, 116 and 122; steep caps suit flat surroundings and can overshoot round
    /// ones (a cow's head: 2 may suit such a scan). See src/surface/outside.rs.
    #[arg(long, default_value_t = crate::surface::outside::MOUTH_SLOPE, value_name = "S", value_parser = mouth_slope)]
    pub mouth_slope: f64,
    /// How far the caps over holes are pushed outward (--mouth-points): inside points at the
    /// cap's crossings nearest to the rims held, farther than 3.5 median spacings of the data
    /// from them, with targets this fraction of the crossing's depth below the tangent plane of
    /// its rim point deep. A cap over a flat base stays flat, one over a curved flank bulges, one
    /// over the cut end of a part rises most; 0 turns it off. On the 240 holed sets of the
    /// surface benchmark 0.75 met every quality target on 173 (a quarter of the distance from
    /// the data, the rule before, on 161); over a rounded end (a cow's head) it can carry the cap
    /// past the truth. See src/surface/outside.rs.
    #[arg(long, default_value_t = crate::surface::outside::CAP_BULGE, value_name = "A", value_parser = cap_bulge)]
    pub cap_bulge: f64,
    /// Points of level 0 of the two-level compactly supported fit (--method csrbf with --surface
    /// auto or offsurface): a dense off-surface fit of this many points chosen evenly over space,
    /// the carrier of the Wendland spline through all points. At 12,000-16,000 points 4000 gave
    /// a lower truth -> mesh distance than 2000 on 12 of 12 sets and a lower mesh -> truth on 11
    /// (README.md, "Two levels for the compactly supported method"), for about 1 s more. Where
    /// the dense fit of that many does not fit the ranks' memory, level 0 takes the most points
    /// whose fit does (at least 50), and the run says so.
    #[arg(long, default_value = "4000", value_name = "N", value_parser = coarse_points)]
    pub coarse_points: usize,
    #[command(flatten)]
    pub grid: GridArgs,
    /// The options given on the command line (their field names), for the warning about those
    /// that have no effect on the fit the run makes ([`Cli::parse_noting_given`]).
    #[arg(skip)]
    pub given: Vec<String>,
}

/// `--lookahead`: on or off as asked, or None for the layout's default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LookAhead(pub Option<bool>);

/// The carrier `fit` uses: chosen with the surface method, or the one given.
#[derive(Debug, Clone, PartialEq)]
pub enum FitCarrier {
    /// `--carrier auto`: [`crate::app::fit::surface::AUTO_CARRIER`] for the off-surface fit, the
    /// fitted ball for the plain carrier method.
    Auto,
    Given(Carrier),
}

/// What `fit` fits the spline to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface {
    Auto,
    OffSurface,
    Carrier,
}

/// How `fit` builds the spline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    Auto,
    Dense,
    Csrbf,
}

/// The radial function asked for: a global Green's function, a compactly supported Wendland
/// function (its support is settled once the points are known), or the method's default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KernelChoice {
    Auto,
    Global(Kernel),
    /// Wendland function of smoothness C^(2s): 0, 1 or 2 -> wendland0, wendland2, wendland4.
    Wendland(u8),
}

/// The sparse solver of `--method csrbf`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SparseSolver {
    Auto,
    Cholesky,
    Envelope,
    Mumps,
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// A model written by `volspline fit` or `volspline contours` (PREFIX.model.h5), or an FRep
    /// expression over models, carriers and numbers, e.g.
    /// 'blend_union(a.model.h5, translate(b.model.h5, 1,0,0), 0.1, 0.2, 0.2)'. Operations: union,
    /// intersection, difference, complement, blend_union, blend_intersection (e1, e2, a0, a1, a2),
    /// offset(e, d), translate(e, dx,dy,dz), rotate(e, ax,ay,az, degrees), scale(e, s),
    /// carrier(MODEL, SPEC). Operands are compared in length units (README.md, "Expressions").
    #[arg(value_name = "MODEL|EXPR", value_parser = with(Syntax::parse))]
    pub model: Syntax,
    /// Output prefix: writes PREFIX.hdf, PREFIX.ply.
    #[arg(long, value_name = "PREFIX")]
    pub out: PathBuf,
    /// Box to evaluate: xmin,ymin,zmin,xmax,ymax,zmax (default: the data's box plus --margin).
    #[arg(long, value_name = "BOX", allow_hyphen_values = true, value_parser = with(parse_bounds))]
    pub bounds: Option<([f64; 3], [f64; 3])>,
    /// Also write PREFIX.trimmed.ply, as `fit --trim F` does, from the data points the model
    /// records (a model of scattered points written by `fit`; F = 2 when no value is given).
    #[arg(long, value_name = "F", num_args = 0..=1, default_missing_value = "2", value_parser = trim_factor)]
    pub trim: Option<f64>,
    #[command(flatten)]
    pub grid: GridArgs,
}

#[derive(Debug, Args)]
pub struct MorphArgs {
    /// The solid at t = 0: a model file or an expression (as for `eval`).
    #[arg(value_name = "A", value_parser = with(Syntax::parse))]
    pub a: Syntax,
    /// The solid at t = 1.
    #[arg(value_name = "B", value_parser = with(Syntax::parse))]
    pub b: Syntax,
    /// Output prefix: writes PREFIX_000.hdf, PREFIX_000.ply, ... and PREFIX.hdf.series.
    #[arg(long, value_name = "PREFIX")]
    pub out: PathBuf,
    /// Number of frames K, at t = 0, 1/(K-1), ..., 1.
    #[arg(long, default_value = "10", value_name = "K", value_parser = frames)]
    pub frames: usize,
    /// Point pairs `x y z x' y' z'` per line (at least 4, not all on one plane): the feature of A
    /// at (x,y,z) travels to the feature of B at (x',y',z') along a volume-spline space mapping.
    #[arg(long, value_name = "FILE")]
    pub pairs: Option<PathBuf>,
    /// Box to evaluate: xmin,ymin,zmin,xmax,ymax,zmax (default: the box of both solids' data plus
    /// --margin).
    #[arg(long, value_name = "BOX", allow_hyphen_values = true, value_parser = with(parse_bounds))]
    pub bounds: Option<([f64; 3], [f64; 3])>,
    #[command(flatten)]
    pub grid: GridArgs,
}

#[derive(Debug, Args)]
pub struct ContoursArgs {
    /// Contour file: `slice z Z` / `slice plane O U V` / `slice omega W O` lines, each followed by
    /// `contour` blocks of in-plane points `a b` (format in README.md).
    pub input: PathBuf,
    /// Output prefix: writes PREFIX.model.h5, PREFIX.hdf, PREFIX.ply.
    #[arg(long, value_name = "PREFIX")]
    pub out: PathBuf,
    /// Interpolation between slices: linear, cubic (cardinal natural cubic splines in the slice
    /// parameter: C^2, but may overshoot where the sections change abruptly) or monotone (C^1
    /// cubic Hermite that stays between the two neighbouring slices' values: no overshoot).
    #[arg(long, default_value = "linear", value_name = "linear|cubic|monotone", value_parser = with(Interp::parse))]
    pub interp: Interp,
    /// Interpolation of the section frames of non-parallel slices: slerp (quaternion geodesic) or
    /// log (exp((1-t) ln M_i + t ln M_i+1)).
    #[arg(long, default_value = "slerp", value_name = "slerp|log", value_parser = with(Orient::parse))]
    pub orient: Orient,
    /// Green's function of the 2D section splines: r2log (m = 2, thin plate, polynomial 1, x, y)
    /// or r4log (m = 3; needs --carrier union).
    #[arg(long, default_value = "r2log", value_name = "r2log|r4log", value_parser = kernel_2d)]
    pub kernel: Kernel,
    /// Carrier of each section: disc (one disc round the slice) or union (R-union of one disc per
    /// contour, bounded by the slice's disc: keeps neighbouring contours, such as legs, apart).
    #[arg(long, default_value = "disc", value_name = "disc|union", value_parser = with(SectionCarrier::parse))]
    pub carrier: SectionCarrier,
    /// Points of a slice closer than this fraction of the slice's diagonal are merged into one.
    #[arg(long, allow_hyphen_values = true, default_value = "1e-6", value_name = "F", value_parser = merge_tol)]
    pub merge_tol: f64,
    /// Do not write the picture PREFIX.png of the solid.
    #[arg(long)]
    pub no_preview: bool,
    #[command(flatten)]
    pub grid: GridArgs,
}

#[derive(Debug, Args)]
pub struct SliceArgs {
    /// Triangle mesh: .obj or .ply with faces, or .stl.
    pub mesh: PathBuf,
    /// The contour file to write.
    #[arg(long, value_name = "CONTOURS")]
    pub out: PathBuf,
    /// Planes: AXIS:N (N parallel planes across the mesh, AXIS x, y or z) or fan-AXIS:N (N planes
    /// sweeping along AXIS while turning about a hinge line outside the mesh: non-parallel).
    #[arg(long, default_value = "z:40", value_name = "SPEC", value_parser = with(PlaneFamily::parse))]
    pub planes: PlaneFamily,
    /// Also write the run's figures (planes, slices, contours, points, the cuts merged, chains
    /// joined, crossings, stage seconds) as `key,value` CSV to this file.
    #[arg(long, value_name = "FILE")]
    pub timings: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct GridArgs {
    /// Grid nodes: N along the longest side of the box with cubic cells, or NX,NY,NZ.
    #[arg(long, allow_hyphen_values = true, default_value = "64", value_name = "N|NX,NY,NZ", value_parser = with(GridSize::parse))]
    pub grid: GridSize,
    /// Margin added on every side of the data's bounding box, as a fraction of its longest side;
    /// auto: 0.05, and where the solid reaches a face of the grid, the grid grows there by whole
    /// cells at the same spacing (5 % of its longest side, twice that the next step, ...) and is
    /// evaluated again, so the surface comes out closed (fit, contours and eval of a model; at
    /// most 6 steps and 8 times the nodes).
    #[arg(long, allow_hyphen_values = true, default_value = "auto", value_name = "auto|F", value_parser = with(Margin::parse))]
    pub margin: Margin,
    /// Threads per rank (0: the cores of this node divided by the ranks on it).
    #[arg(long, allow_negative_numbers = true, default_value = "0", value_name = "T", value_parser = threads)]
    pub threads: usize,
    /// Also write the run's figures (sizes, stage min/max seconds, residual, peak memory) as
    /// `key,value` CSV to this file, for scaling studies.
    #[arg(long, value_name = "FILE")]
    pub timings: Option<PathBuf>,
    /// Progress bars of the dense solve and the grid evaluation on rank 0's standard error: auto
    /// (where that is a terminal; under Open MPI's mpirun it is a pipe, so none), on (always:
    /// under mpirun they reach the terminal through it) or off.
    #[arg(long, default_value = "auto", value_name = "auto|on|off", value_parser = progress::Mode::parse)]
    pub progress: progress::Mode,
    /// The most memory each rank may use: bytes with a unit, as 800MB, 4GB or 2GiB (default: the
    /// node's available memory and the job's cgroup limit, shared by the ranks on the node). The
    /// checks before each heavy stage, the choice of --method auto and whether a 2D factor is
    /// kept for later fits go by the smaller of this and the system's figure.
    #[arg(long, value_name = "SIZE", value_parser = memory_size)]
    pub memory_per_rank: Option<f64>,
    /// Also write the mean and Gaussian curvature of the level surfaces: arrays
    /// `mean_curvature` and `gaussian_curvature` in PREFIX.hdf (at every node, of the level
    /// surface through it) and vertex properties of the same names in PREFIX.ply.
    #[arg(long)]
    pub curvature: bool,
}

impl GridArgs {
    /// Whether the grid may grow where the solid reaches its faces: `--margin auto` with the
    /// nodes along the longest side given (node counts NX,NY,NZ fix the grid). Callers add
    /// their own conditions (no `--bounds`, a bounded solid).
    pub fn may_grow(&self) -> bool {
        self.margin.grow && matches!(self.grid, GridSize::Longest(_))
    }
}

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The solid: a model written by `volspline fit` or `volspline contours` (PREFIX.model.h5), or
    /// an FRep expression over models, carriers and numbers, as `eval` takes it (README.md,
    /// "Expressions").
    #[arg(value_name = "MODEL|EXPR")]
    pub model: String,
    /// The picture to write (.png).
    #[arg(long, value_name = "PNG")]
    pub out: PathBuf,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Threads per rank (0: the cores of this node divided by the ranks on it).
    #[arg(long, allow_negative_numbers = true, default_value = "0", value_name = "T", value_parser = threads)]
    pub threads: usize,
    /// Also write the run's figures as `key,value` CSV to this file.
    #[arg(long, value_name = "FILE")]
    pub timings: Option<PathBuf>,
    /// A progress bar of the ray casting (rank 0's rows) on rank 0's standard error: auto (where
    /// that is a terminal; under Open MPI's mpirun it is a pipe, so none), on (always) or off.
    #[arg(long, default_value = "auto", value_name = "auto|on|off", value_parser = progress::Mode::parse)]
    pub progress: progress::Mode,
}

/// The camera and the colouring of a picture.
#[derive(Debug, Clone, Args)]
pub struct ViewArgs {
    /// Degrees about the up axis from which the camera looks at the centre of the solid's box.
    #[arg(long, allow_hyphen_values = true, default_value = "30", value_name = "DEG", value_parser = azimuth)]
    pub azimuth: f64,
    /// Degrees above the plane normal to the up axis (-90 to 90).
    #[arg(long, allow_hyphen_values = true, default_value = "20", value_name = "DEG", value_parser = elevation)]
    pub elevation: f64,
    /// Distance of the camera from the centre of the solid's box (default: the box just fills
    /// the view).
    #[arg(long, allow_hyphen_values = true, value_name = "D", value_parser = distance)]
    pub distance: Option<f64>,
    /// Picture size in pixels, WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512", value_name = "WxH", value_parser = size)]
    pub size: (usize, usize),
    /// The axis that points up in the picture: x, y or z.
    #[arg(long, default_value = "y", value_name = "x|y|z", value_parser = axis)]
    pub up: Axis,
    /// Colouring: shading (a matte solid lit from the camera's upper left) or curvature (mean
    /// curvature, red convex, blue concave, white flat, shaded).
    #[arg(long, default_value = "shading", value_name = "shading|curvature", value_parser = colouring)]
    pub color: Colouring,
}

impl Command {
    /// The files the command line names: inputs, models of expressions, the output prefix or
    /// file and the `--timings` file, as given (relative paths are resolved by each rank in its
    /// own working directory).
    pub fn paths(&self) -> Vec<PathBuf> {
        let mut paths = match self {
            Command::Fit(a) => vec![a.input.clone(), a.out.clone()],
            Command::Eval(a) => [a.model.models(), vec![a.out.clone()]].concat(),
            Command::Morph(a) => {
                [a.a.models(), a.b.models(), vec![a.out.clone()], a.pairs.iter().cloned().collect()].concat()
            }
            Command::Contours(a) => vec![a.input.clone(), a.out.clone()],
            Command::Slice(a) => vec![a.mesh.clone(), a.out.clone()],
            Command::Render(a) => {
                [Syntax::parse(&a.model).map(|e| e.models()).unwrap_or_default(), vec![a.out.clone()]]
                    .concat()
            }
        };
        let timings = match self {
            Command::Fit(a) => &a.grid.timings,
            Command::Eval(a) => &a.grid.timings,
            Command::Morph(a) => &a.grid.timings,
            Command::Contours(a) => &a.grid.timings,
            Command::Slice(a) => &a.timings,
            Command::Render(a) => &a.timings,
        };
        paths.extend(timings.iter().cloned());
        paths
    }
}

impl Cli {
    /// The command line parsed as [`Parser::try_parse`] does, noting which of `fit`'s options
    /// were given (not defaults) in [`FitArgs::given`].
    pub fn parse_noting_given() -> Result<Cli, clap::Error> {
        let matches = Cli::command().try_get_matches()?;
        let mut cli = Cli::from_arg_matches(&matches)?;
        if let (Command::Fit(a), Some((_, sub))) = (&mut cli.command, matches.subcommand()) {
            a.given = sub
                .ids()
                .filter(|id| sub.value_source(id.as_str()) == Some(ValueSource::CommandLine))
                .map(|id| id.to_string())
                .collect();
        }
        Ok(cli)
    }

    /// The `--progress` mode (auto for the commands without one).
    pub fn progress(&self) -> progress::Mode {
        match &self.command {
            Command::Fit(a) => a.grid.progress,
            Command::Eval(a) => a.grid.progress,
            Command::Morph(a) => a.grid.progress,
            Command::Contours(a) => a.grid.progress,
            Command::Render(a) => a.progress,
            Command::Slice(_) => progress::Mode::Auto,
        }
    }

    /// The `--memory-per-rank` limit in bytes, for the commands that take it.
    pub fn memory_per_rank(&self) -> Option<f64> {
        match &self.command {
            Command::Fit(a) => a.grid.memory_per_rank,
            Command::Eval(a) => a.grid.memory_per_rank,
            Command::Morph(a) => a.grid.memory_per_rank,
            Command::Contours(a) => a.grid.memory_per_rank,
            Command::Slice(_) | Command::Render(_) => None,
        }
    }

    /// The --threads value of whichever command was given.
    pub fn threads(&self) -> usize {
        match &self.command {
            Command::Fit(a) => a.grid.threads,
            Command::Eval(a) => a.grid.threads,
            Command::Morph(a) => a.grid.threads,
            Command::Contours(a) => a.grid.threads,
            Command::Slice(_) => 1,
            Command::Render(a) => a.threads,
        }
    }
}

/// Threads per rank: for 0 (the default) this node's cores divided by the ranks on it, at least 1,
/// so that the defaults never oversubscribe the cores; otherwise the count asked for, but at most
/// the CPUs this process may run on (its affinity mask): more threads would only take turns on
/// them, and the dense solvers' threads, which wait for each other at every panel, then run
/// hundreds of times slower (1000 threads on 2 CPUs: 134 s for a 0.07 s solve).
pub fn default_threads(requested: usize) -> usize {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    if requested > 0 {
        return requested.min(cpus);
    }
    (cpus / ranks_on_this_node()).max(1)
}

/// The warning when `--threads` asks for more threads than the CPUs this process may run on (its
/// affinity mask, which the launcher sets: Open MPI binds each rank to one core when it starts
/// two or fewer, `srun` to its `--cpus-per-task`): as many threads as those CPUs are started
/// ([`default_threads`]). None for the default (0), which counts only those CPUs.
pub fn threads_warning(requested: usize) -> Option<String> {
    let cpus = std::thread::available_parallelism().ok()?.get();
    (requested > cpus).then(|| {
        format!(
            "--threads {requested}, but this rank may run on {cpus} CPU(s) (its affinity mask, as the \
             launcher set it: Open MPI binds each rank to a core when it starts 2 or fewer), so {cpus} \
             thread(s) are started: more would only take turns on them; for {requested} threads start the \
             ranks unbound (mpirun --bind-to none) or with {requested} CPUs each (mpirun --map-by \
             slot:PE={requested}, srun --cpus-per-task={requested})"
        )
    })
}

/// The number of ranks the launcher started on this node (1 without a launcher).
pub fn ranks_on_this_node() -> usize {
    ["OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS", "MV2_COMM_WORLD_LOCAL_SIZE", "SLURM_NTASKS_PER_NODE"]
        .iter()
        .find_map(|v| std::env::var(v).ok()?.parse::<usize>().ok())
        .unwrap_or(1)
        .max(1)
}

/// This process's rank as the launcher announces it, before MPI is started (0 without one).
pub fn launcher_rank() -> usize {
    ["OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK", "SLURM_PROCID"]
        .iter()
        .find_map(|v| std::env::var(v).ok()?.parse().ok())
        .unwrap_or(0)
}

// Value parsers: the library's own parsers, with a usage error's message as clap's reason.

type Parsed<T> = std::result::Result<T, String>;

/// A library parser as a clap value parser.
fn with<T: 'static>(
    parse: fn(&str) -> Result<T>,
) -> impl Fn(&str) -> Parsed<T> + Clone + Send + Sync + 'static {
    move |s| reason(parse(s))
}

fn reason<T>(r: Result<T>) -> Parsed<T> {
    r.map_err(|e| match e {
        Error::Usage(m) => m,
        other => other.to_string(),
    })
}

/// `fit --denoise`: `Some(on)` as given, `None` for auto.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Denoise(pub Option<bool>);

/// `--orient-side`: the side vote off, on in the orientation, tried as one turn after the blob
/// search, or both ways with the better fit kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SideVote {
    Off,
    On,
    Try,
    Both,
}

fn side_vote_mode(s: &str) -> Parsed<SideVote> {
    match s {
        "off" => Ok(SideVote::Off),
        "on" => Ok(SideVote::On),
        "try" => Ok(SideVote::Try),
        "both" => Ok(SideVote::Both),
        other => Err(format!("expected try, on, off or both, not '{other}'")),
    }
}

fn denoise_mode(s: &str) -> Parsed<Denoise> {
    on_off_auto(s).map(|LookAhead(x)| Denoise(x))
}

fn on_off_auto(s: &str) -> Parsed<LookAhead> {
    match s {
        "auto" => Ok(LookAhead(None)),
        other => on_off(other)
            .map(|b| LookAhead(Some(b)))
            .map_err(|_| format!("expected auto, on or off, not '{other}'")),
    }
}

fn on_off(s: &str) -> Parsed<bool> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        other => Err(format!("expected on or off, not '{other}'")),
    }
}

fn carrier_3d(s: &str) -> Parsed<Carrier> {
    reason(Carrier::parse(s, 3))
}

fn fit_carrier(s: &str) -> Parsed<FitCarrier> {
    if s == "auto" {
        return Ok(FitCarrier::Auto);
    }
    carrier_3d(s).map(FitCarrier::Given)
}

fn kernel_choice(s: &str) -> Parsed<KernelChoice> {
    match s {
        "auto" => Ok(KernelChoice::Auto),
        "wendland0" => Ok(KernelChoice::Wendland(0)),
        "wendland2" => Ok(KernelChoice::Wendland(1)),
        "wendland4" => Ok(KernelChoice::Wendland(2)),
        other => Kernel::from_name_3d(other).map(KernelChoice::Global).map_err(|_| {
            format!("unknown kernel '{other}' (expected auto, r, r3, wendland0, wendland2 or wendland4)")
        }),
    }
}

fn method(s: &str) -> Parsed<Method> {
    match s {
        "auto" => Ok(Method::Auto),
        "dense" => Ok(Method::Dense),
        "csrbf" => Ok(Method::Csrbf),
        other => Err(format!("unknown method '{other}' (expected auto, dense or csrbf)")),
    }
}

fn surface(s: &str) -> Parsed<Surface> {
    match s {
        "auto" => Ok(Surface::Auto),
        "offsurface" => Ok(Surface::OffSurface),
        "carrier" => Ok(Surface::Carrier),
        other => Err(format!("unknown surface method '{other}' (expected auto, offsurface or carrier)")),
    }
}

fn off_deal(s: &str) -> Parsed<Deal> {
    match s {
        "index" => Ok(Deal::Index),
        "neighbours" => Ok(Deal::Neighbours),
        other => {
            Err(format!("unknown way to deal off-surface points '{other}' (expected index or neighbours)"))
        }
    }
}

fn off_rate(s: &str) -> Parsed<f64> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v <= 2.0 => Ok(v),
        _ => Err(format!("'{s}' is not a number of off-surface points per data point in (0, 2]")),
    }
}

fn share(s: &str) -> Parsed<f64> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not a share in [0, 1]")),
    }
}

fn smoothing(s: &str) -> Parsed<f64> {
    match s.trim().parse::<f64>() {
        Ok(v) if v >= 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a smoothing: a finite number >= 0")),
    }
}

fn trim_factor(s: &str) -> Parsed<f64> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a trimming factor: a positive multiple of the data's median spacing")),
    }
}

fn mouth_slope(s: &str) -> Parsed<f64> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v <= 10.0 => Ok(v),
        _ => Err(format!("'{s}' is not a slope of the mouth points' targets: a number in (0, 10]")),
    }
}

fn cap_bulge(s: &str) -> Parsed<f64> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!(
            "'{s}' is not a cap bulge: a fraction of the depth below the rim's tangent plane in [0, 1]"
        )),
    }
}

fn coarse_points(s: &str) -> Parsed<usize> {
    match s.trim().parse::<usize>() {
        Ok(k) if (50..=100_000).contains(&k) => Ok(k),
        _ => Err(format!("'{s}' is not a number of level-0 points from 50 to 100000")),
    }
}

fn sparse_solver(s: &str) -> Parsed<SparseSolver> {
    match s {
        "auto" => Ok(SparseSolver::Auto),
        "cholesky" => Ok(SparseSolver::Cholesky),
        "envelope" => Ok(SparseSolver::Envelope),
        "mumps" => Ok(SparseSolver::Mumps),
        other => Err(format!("unknown sparse solver '{other}' (expected auto, cholesky, envelope or mumps)")),
    }
}

fn support(s: &str) -> Parsed<f64> {
    number_in(s, f64::MIN_POSITIVE..=4.0, "(0, 4] (the data's box has diagonal 2 inside)")
}

fn leaf(s: &str) -> Parsed<usize> {
    match s.trim().parse::<usize>() {
        Ok(k) if (1..=100_000).contains(&k) => Ok(k),
        _ => Err(format!("'{s}': expected a leaf capacity in 1..=100000")),
    }
}

fn kernel_2d(s: &str) -> Parsed<Kernel> {
    match s {
        "r2log" => reason(Kernel::new(2, 2)),
        "r4log" => reason(Kernel::new(2, 3)),
        other => Err(format!("unknown kernel '{other}' (expected r2log or r4log)")),
    }
}

/// A number in `range`, described as `what` when it is not.
fn number_in(s: &str, range: impl std::ops::RangeBounds<f64>, what: &str) -> Parsed<f64> {
    let v: f64 = s.trim().parse().map_err(|_| format!("'{s}' is not a number"))?;
    if range.contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v}: expected a number in {what}"))
    }
}

/// Most threads a rank may start: far beyond any node's cores, short of exhausting the process.
pub const MAX_THREADS: usize = 1024;

fn threads(s: &str) -> Parsed<usize> {
    match s.trim().parse::<usize>() {
        Ok(t) if t <= MAX_THREADS => Ok(t),
        Ok(t) => Err(format!("{t} threads per rank: at most {MAX_THREADS} (use about the cores per rank)")),
        Err(_) => Err(format!("'{s}' is not a thread count")),
    }
}

/// Most frames of a metamorphosis.
pub const MAX_FRAMES: usize = 1000;

fn frames(s: &str) -> Parsed<usize> {
    match s.trim().parse::<usize>() {
        Ok(k) if (2..=MAX_FRAMES).contains(&k) => Ok(k),
        _ => Err(format!("'{s}': expected a frame count in 2..={MAX_FRAMES}")),
    }
}

fn azimuth(s: &str) -> Parsed<f64> {
    number_in(s, -360.0..=360.0, "[-360, 360] degrees")
}

fn elevation(s: &str) -> Parsed<f64> {
    number_in(s, -90.0..=90.0, "[-90, 90] degrees")
}

fn distance(s: &str) -> Parsed<f64> {
    number_in(s, f64::MIN_POSITIVE..=f64::MAX, "(0, inf): a positive distance")
}

/// The largest picture side in pixels.
pub const MAX_PICTURE_SIDE: usize = 16384;
/// The most pixels of a picture (rank 0 holds 32 bytes per pixel while it colours them).
pub const MAX_PICTURE_PIXELS: usize = 1 << 26;

fn size(s: &str) -> Parsed<(usize, usize)> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let side = |t: &str| t.trim().parse::<usize>().ok().filter(|v| (1..=MAX_PICTURE_SIDE).contains(v));
    match parts.as_slice() {
        [w, h] => match (side(w), side(h)) {
            (Some(w), Some(h)) if w * h > MAX_PICTURE_PIXELS => {
                Err(format!("'{s}': {} pixels, more than the {MAX_PICTURE_PIXELS} a picture may have", w * h))
            }
            (Some(w), Some(h)) => Ok((w, h)),
            _ => Err(format!("'{s}': each side must be a whole number of pixels in 1..={MAX_PICTURE_SIDE}")),
        },
        _ => Err(format!("'{s}': expected WIDTHxHEIGHT, such as 512x512")),
    }
}

fn axis(s: &str) -> Parsed<Axis> {
    match s {
        "x" => Ok(Axis::X),
        "y" => Ok(Axis::Y),
        "z" => Ok(Axis::Z),
        other => Err(format!("unknown axis '{other}' (expected x, y or z)")),
    }
}

fn colouring(s: &str) -> Parsed<Colouring> {
    match s {
        "shading" => Ok(Colouring::Shading),
        "curvature" => Ok(Colouring::Curvature),
        other => Err(format!("unknown colouring '{other}' (expected shading or curvature)")),
    }
}

/// A memory size: a number and a unit, KB, MB, GB, TB (powers of 1000; K, M, G, T alike) or KiB,
/// MiB, GiB, TiB (powers of 1024), at least 1 MB and at most 1 PB.
fn memory_size(s: &str) -> Parsed<f64> {
    let t = s.trim();
    let split = t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len());
    let (number, unit) = (t[..split].trim(), &t[split..]);
    let scale = match unit.to_ascii_uppercase().as_str() {
        "K" | "KB" => 1e3,
        "M" | "MB" => 1e6,
        "G" | "GB" => 1e9,
        "T" | "TB" => 1e12,
        "KIB" => 1024.0,
        "MIB" => 1024f64.powi(2),
        "GIB" => 1024f64.powi(3),
        "TIB" => 1024f64.powi(4),
        "" => return Err(format!("'{s}' has no unit: write it as 800MB, 4GB or 2GiB")),
        other => {
            return Err(format!("'{other}' is not a memory unit (KB, MB, GB, TB, KiB, MiB, GiB or TiB)"))
        }
    };
    match number.parse::<f64>() {
        Ok(v) if v.is_finite() && (1e6..=1e15).contains(&(v * scale)) => Ok(v * scale),
        Ok(_) => Err(format!("'{s}': expected a memory size from 1MB to 1PB")),
        Err(_) => Err(format!("'{s}' is not a memory size (such as 800MB, 4GB or 2GiB)")),
    }
}

fn merge_tol(s: &str) -> Parsed<f64> {
    number_in(s, 0.0..0.1, "[0, 0.1)")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> std::result::Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("volspline").chain(args.iter().copied()))
    }

    #[test]
    fn options_arrive_typed() {
        let cli =
            parse(&["fit", "a.xyz", "--out", "o", "--solver", "lu", "--carrier", "ball:0,0,0,2"]).unwrap();
        let Command::Fit(a) = cli.command else { panic!("fit") };
        assert_eq!(a.solver, SolverKind::Lu);
        assert_eq!(a.precision, Precision::F64);
        assert_eq!(a.lookahead, LookAhead(None));
        assert_eq!(a.kernel, KernelChoice::Auto);
        assert_eq!(a.method, Method::Auto);
        assert_eq!(a.leaf, 10);
        assert_eq!(a.grid.grid, GridSize::Longest(64));
        assert_eq!(a.grid.margin, Margin { fraction: 0.05, grow: true });
        assert_eq!(a.merge_tol, 1e-6);
        assert!(a.drop_isolated);
        assert_eq!(
            (a.surface, a.off_points, a.doubtful_share, a.off_deal),
            (Surface::Auto, 0.5, 0.4, Deal::Neighbours)
        );
        assert!(matches!(&a.carrier, FitCarrier::Given(c) if c.to_string().starts_with("ball:")));
        let cli =
            parse(&["fit", "a.xyz", "--out", "o", "--surface", "carrier", "--off-points", "2"]).unwrap();
        let Command::Fit(a) = cli.command else { panic!("fit") };
        assert_eq!(a.carrier, FitCarrier::Auto);
        assert_eq!((a.surface, a.off_points), (Surface::Carrier, 2.0));
        assert_eq!(a.mouth_slope, crate::surface::outside::MOUTH_SLOPE);
        let cli = parse(&["fit", "a.xyz", "--out", "o", "--mouth-slope", "3.5"]).unwrap();
        let Command::Fit(a) = cli.command else { panic!("fit") };
        assert_eq!(a.mouth_slope, 3.5);
        assert_eq!(a.cap_bulge, crate::surface::outside::CAP_BULGE);
        let cli = parse(&["fit", "a.xyz", "--out", "o", "--cap-bulge", "0"]).unwrap();
        let Command::Fit(a) = cli.command else { panic!("fit") };
        assert_eq!(a.cap_bulge, 0.0);
        for bad in ["-0.1", "1.5", "nan", "x"] {
            assert!(parse(&["fit", "a.xyz", "--out", "o", "--cap-bulge", bad]).is_err(), "{bad}");
        }
        let cli = parse(&["fit", "a.xyz", "--out", "o", "--off-deal", "index"]).unwrap();
        let Command::Fit(a) = cli.command else { panic!("fit") };
        assert_eq!(a.off_deal, Deal::Index);
        let cli = parse(&["fit", "a.xyz", "--out", "o", "--margin", "0.2"]).unwrap();
        let Command::Fit(a) = cli.command else { panic!("fit") };
        assert_eq!(a.grid.margin, Margin { fraction: 0.2, grow: false });
        for (text, side) in
            [("off", SideVote::Off), ("on", SideVote::On), ("try", SideVote::Try), ("both", SideVote::Both)]
        {
            let cli = parse(&["fit", "a.xyz", "--out", "o", "--orient-side", text]).unwrap();
            let Command::Fit(a) = cli.command else { panic!("fit") };
            assert_eq!(a.orient_side, side);
        }
        let Command::Fit(a) = parse(&["fit", "a.xyz", "--out", "o"]).unwrap().command else { panic!("fit") };
        assert_eq!(a.orient_side, SideVote::Try);
        let err = parse(&["fit", "a.xyz", "--out", "o", "--orient-side", "auto"]).unwrap_err().to_string();
        assert!(err.contains("expected try, on, off or both, not 'auto'"), "{err}");
    }

    #[test]
    fn memory_sizes_take_decimal_and_binary_units() {
        for (text, bytes) in
            [("800MB", 8e8), ("4GB", 4e9), ("4g", 4e9), (" 1.5 TB", 1.5e12), ("2GiB", 2147483648.0)]
        {
            assert_eq!(memory_size(text), Ok(bytes), "{text}");
        }
        let cli = parse(&["contours", "c.txt", "--out", "o", "--memory-per-rank", "512MiB"]).unwrap();
        assert_eq!(cli.memory_per_rank(), Some(512.0 * 1024.0 * 1024.0));
        assert_eq!(parse(&["fit", "a.xyz", "--out", "o"]).unwrap().memory_per_rank(), None);
        assert!(memory_size("12").unwrap_err().contains("no unit"));
    }

    #[test]
    fn bad_values_are_usage_errors_before_anything_runs() {
        for bad in [
            &["fit", "a.xyz", "--out", "o", "--solver", "gauss"][..],
            &["fit", "a.xyz", "--out", "o", "--precision", "half"][..],
            &["fit", "a.xyz", "--out", "o", "--lookahead", "yes"][..],
            &["fit", "a.xyz", "--out", "o", "--carrier", "cube"],
            &["fit", "a.xyz", "--out", "o", "--margin", "-1"],
            &["fit", "a.xyz", "--out", "o", "--margin", "wide"],
            &["fit", "a.xyz", "--out", "o", "--merge-tol", "0.5"],
            &["fit", "a.xyz", "--out", "o", "--grid", "1"],
            &["eval", "m.h5", "--out", "o", "--bounds", "0,0,0,1,1"],
            &["contours", "c.txt", "--out", "o", "--interp", "quintic"],
            &["slice", "m.obj", "--out", "c.txt", "--planes", "w:3"],
            &["fit", "a.xyz", "--out", "o", "--threads", "20000"],
            &["fit", "a.xyz", "--out", "o", "--kernel", "wendland3"],
            &["fit", "a.xyz", "--out", "o", "--method", "sparse"],
            &["fit", "a.xyz", "--out", "o", "--support", "0"],
            &["fit", "a.xyz", "--out", "o", "--leaf", "0"],
            &["fit", "a.xyz", "--out", "o", "--mouth-slope", "0"],
            &["fit", "a.xyz", "--out", "o", "--mouth-slope", "11"],
            &["fit", "a.xyz", "--out", "o", "--mouth-slope", "NaN"],
            &["eval", "union(a.model.h5,", "--out", "o"],
            &["morph", "a.model.h5", "b.model.h5", "--out", "o", "--frames", "1"],
            &["render", "m.h5", "--out", "p.png", "--size", "0x10"],
            &["render", "m.h5", "--out", "p.png", "--size", "512"],
            &["render", "m.h5", "--out", "p.png", "--size", "16384x16384"],
            &["render", "m.h5", "--out", "p.png", "--elevation", "91"],
            &["render", "m.h5", "--out", "p.png", "--distance", "-1"],
            &["render", "m.h5", "--out", "p.png", "--up", "w"],
            &["render", "m.h5", "--out", "p.png", "--color", "rainbow"],
            &["fit", "a.xyz", "--out", "o", "--surface", "poisson"],
            &["fit", "a.xyz", "--out", "o", "--memory-per-rank", "4096"],
            &["fit", "a.xyz", "--out", "o", "--memory-per-rank", "4 bytes"],
            &["fit", "a.xyz", "--out", "o", "--memory-per-rank", "0.5KB"],
            &["eval", "m.h5", "--out", "o", "--memory-per-rank", "-1GB"],
            &["fit", "a.xyz", "--out", "o", "--off-points", "0"],
            &["fit", "a.xyz", "--out", "o", "--off-points", "2.5"],
            &["fit", "a.xyz", "--out", "o", "--off-points", "nan"],
            &["fit", "a.xyz", "--out", "o", "--off-deal", "space"],
        ] {
            let e = parse(bad).unwrap_err();
            assert_eq!(e.exit_code(), 2, "{bad:?}");
        }
    }
}
