//! Off-surface constraints from unoriented points (`--surface offsurface`, the default): noisy
//! scans of a sphere and a torus reconstructed within grid accuracy with the right topology,
//! 1, 2 and 3 ranks against a serial oracle of the constrained system, and the spurious surface
//! of the bunny against the plain carrier method.

mod common;

use std::path::{Path, PathBuf};

use common::{area_samples, area_samples_with_normals, solve_serial, Rng};
use volspline::io::model_file::read_model;
use volspline::io::vtkhdf::read_image;
use volspline::linalg::dist::SolverKind;
use volspline::mesh::{
    connected_components, euler_characteristic, is_closed_manifold_edges, point_mesh_distances,
};
use volspline::par::Solo;
use volspline::spline::hygiene::{prepare, Prepared};
use volspline::spline::{Carrier, Kernel, Model, Spline};
use volspline::surface::blobs::{
    blob_values, lost_solid, paths_to_solid, points_without_solid, sample, sample_nodes, sample_window,
    winding_numbers, Blobs, Lattice, Search, CLEARANCE, INSIDE, OPEN_SPACE, RESTORE_FROM, SECOND_ROUND_FROM,
};
use volspline::surface::choice::{self, unsupported_share};
use volspline::surface::energy::{flip_by_energy, pairs, patch_energy, ENERGY_LIMIT};
use volspline::surface::offsurface::{trusted, Deal, DOUBTFUL_SHARE};
use volspline::surface::outside;
use volspline::surface::rays::{self, RayCheck};
use volspline::surface::support::DataSupport;
use volspline::surface::turns::{self, SideTry, TurnCheck};
use volspline::surface::{
    neighbourhoods, off_points_by_trust, off_value_parts, off_values, off_values_sloped, oriented,
    oriented_with, Doubt, Neighbourhoods, OffPoints,
};

/// The default off-point rate of `volspline fit` (`--off-points`).
const RATE: f64 = 0.5;

/// One off-point rate, 0.4, for every data point whatever its normal: the setup the tests of the
/// later steps (rays, blobs, the clearance choice, the oracles of the whole pipeline) were built
/// and measured on, which the default before trusted normals was. [`UNIFORM_RATE`] for the
/// library's steps.
const UNIFORM: [&str; 4] = ["--off-points", "0.4", "--doubtful-share", "1"];
const UNIFORM_RATE: (f64, f64) = (0.4, 1.0);

/// The turns by unsupported surface (step 7) and the outside and mouth off points after them off: for the
/// tests that measure an earlier step alone, as it was measured before the turns were on by
/// default.
const NO_TURNS: [&str; 6] = ["--orient-turns", "off", "--outside-points", "off", "--mouth-points", "off"];
/// The off points dealt by index. Whether a rule of the default fit fires on a sample depends on
/// which points carry off points; the tests of a rule on a chosen sample pin the dealing on which
/// it was measured there (the rules are the same for either dealing).
const BY_INDEX: [&str; 2] = ["--off-deal", "index"];
/// The fitted ball as the carrier: the figures of the tests of single steps, and the serial
/// oracles' carrier, were measured with it, before the off-surface fit's carrier became the
/// fitted ellipsoid (`--carrier auto`, tested on its own).
const BALL: [&str; 2] = ["--carrier", "ball"];
/// The oracle's off-point rates of [`UNIFORM`] and of the default options, dealt among
/// neighbours (the default), and of the default options dealt by index.
const UNIFORM_DEALT: OffRates = (UNIFORM_RATE, Deal::Neighbours);
const DEFAULT_DEALT: OffRates = ((RATE, DOUBTFUL_SHARE), Deal::Neighbours);
/// Off-point options of the serial oracle: the rate for trusted normals and the share of it for
/// doubtful ones, and the dealing.
type OffRates = ((f64, f64), Deal);

/// `n` points of a surface given by `at(u, v)` for u, v uniform in [0, 1) (area-uniform for the
/// parametrisations below), with Gaussian noise of `sigma` on every coordinate.
fn noisy(n: usize, sigma: f64, seed: u64, at: impl Fn(f64, f64) -> [f64; 3]) -> Vec<f64> {
    let mut r = Rng(seed);
    (0..n)
        .flat_map(|_| {
            let p = at(r.unit(), r.unit());
            p.map(|x| x + sigma * r.normal())
        })
        .collect()
}

/// A test shape: name, noisy samples, exact samples, distance to the truth, Euler characteristic.
type Case<'a> = (&'a str, Vec<f64>, Vec<f64>, &'a dyn Fn(&[f64; 3]) -> f64, i64);

/// Fits `pts` with the default surface method and returns the mesh, its grid spacing and the
/// surface line of the report.
fn fit_mesh(name: &str, pts: &[f64], grid: &str, extra: &[&str]) -> (volspline::mesh::TriMesh, f64, String) {
    let dir = common::temp_dir(name);
    let input = dir.join("p.xyz");
    common::write_xyz(&input, pts);
    let prefix = dir.join("s");
    let mut args = vec!["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", grid];
    // the figures of the tests of single steps were measured without the side vote's try in
    // step 7 (the default since; tested on its own) and with the fitted ball as the carrier
    // (the default's fitted ellipsoid since, tested on its own)
    if !extra.contains(&"--orient-side") {
        args.extend_from_slice(&["--orient-side", "off"]);
    }
    if !extra.contains(&"--carrier") {
        args.extend_from_slice(&BALL);
    }
    args.extend_from_slice(extra);
    let text = common::run_ok(1, &args);
    let (g, _) = read_image(&dir.join("s.hdf"), "f").unwrap();
    let surface = text.lines().find(|l| l.contains("surface ")).unwrap_or("").to_string();
    (common::load_mesh(&dir.join("s.ply")), g.spacing[0], surface)
}

#[test]
fn noisy_sphere_and_torus_are_reconstructed_with_their_topology() {
    let c = [0.3, -0.2, 0.1];
    let sphere = |u: f64, v: f64| {
        let (z, t) = (2.0 * u - 1.0, std::f64::consts::TAU * v);
        let r = (1.0 - z * z).sqrt();
        [c[0] + r * t.cos(), c[1] + r * t.sin(), c[2] + z]
    };
    let (big, small) = (1.0, 0.4);
    // area-uniform on the torus: accept the tube angle with probability (R + r cos) / (R + r)
    let torus_points = |n: usize, sigma: f64, seed: u64| {
        let mut r = Rng(seed);
        let mut out = Vec::new();
        while out.len() < 3 * n {
            let (a, b) = (std::f64::consts::TAU * r.unit(), std::f64::consts::TAU * r.unit());
            if r.unit() * (big + small) > big + small * b.cos() {
                continue;
            }
            let w = big + small * b.cos();
            out.extend([w * a.cos(), w * a.sin(), small * b.sin()].map(|x| x + sigma * r.normal()));
        }
        out
    };
    let sphere_dist = |p: &[f64; 3]| ((0..3).map(|d| (p[d] - c[d]).powi(2)).sum::<f64>().sqrt() - 1.0).abs();
    let torus_dist = |p: &[f64; 3]| ((p[0].hypot(p[1]) - big).hypot(p[2]) - small).abs();
    // noise of 0.2 % of the bounding-box diagonal
    let cases: [Case<'_>; 2] = [
        (
            "sphere",
            noisy(1500, 0.002 * 2.0 * 3f64.sqrt(), 7, sphere),
            noisy(400, 0.0, 8, sphere),
            &sphere_dist,
            2,
        ),
        (
            "torus",
            torus_points(2000, 0.002 * (2.0 * 2.8f64 * 2.8 + 0.64).sqrt(), 9),
            torus_points(400, 0.0, 10),
            &torus_dist,
            0,
        ),
    ];
    for (name, pts, truth, dist, euler) in cases {
        let (mesh, h, line) = fit_mesh(name, &pts, "48", &["--carrier", "auto"]);
        let held: Vec<[f64; 3]> = truth.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
        let to_truth: Vec<f64> = mesh.vertices.iter().map(dist).collect();
        let worst = to_truth.iter().fold(0.0f64, |a, &b| a.max(b));
        let mean = to_truth.iter().sum::<f64>() / to_truth.len() as f64;
        let complete = point_mesh_distances(&mesh, &held).into_iter().fold(0.0f64, f64::max);
        println!(
            "{name}: {} vertices, {} components, Euler characteristic {}, mesh -> truth mean {mean:.4} max \
             {worst:.4}, truth -> mesh max {complete:.4}, grid spacing {h:.4}; {line}",
            mesh.vertices.len(),
            connected_components(&mesh),
            euler_characteristic(&mesh)
        );
        assert!(line.contains("surface offsurface"), "{line}");
        assert!(is_closed_manifold_edges(&mesh));
        assert_eq!(connected_components(&mesh), 1, "{name}: extra components");
        assert_eq!(euler_characteristic(&mesh), euler, "{name}: wrong topology");
        assert!(
            worst < 0.5 * h && mean < 0.1 * h,
            "{name}: mesh -> truth mean {mean}, max {worst} (h = {h})"
        );
        assert!(complete < 0.5 * h, "{name}: truth -> mesh max {complete} (h = {h})");
    }
}

/// The serial default fit up to the blob search: the data, the first system (its off points on the
/// sides the ray test left them) and its fit, what the ray test turned, and the blob search.
struct FirstFit {
    k: Kernel,
    data: Prepared,
    prep: Prepared,
    off_count: usize,
    first: Spline,
    turned: RayCheck,
    lattice: Lattice,
    search: Search,
    /// The oriented normals after the ray test, their neighbourhoods and the off points.
    normals: Vec<[f64; 3]>,
    hoods: Neighbourhoods,
    off: OffPoints,
}

/// [`FirstFit`] of `read` (the kernel r, the default carrier), from the library's steps, with the
/// off-point `rate` for trusted normals, the share of it for doubtful ones and the dealing.
fn first_fit(read: &[f64], (rate, deal): OffRates) -> FirstFit {
    let k = Kernel::new(3, 2).unwrap();
    let data = prepare(read, &k, &Carrier::AutoBall, 1e-6).unwrap();
    let hoods = neighbourhoods(&data.centres).unwrap();
    let mut normals = oriented(&Solo, &data.centres, &hoods).unwrap().normals;
    let (mut off, _) =
        off_points_by_trust(&data.centres, &normals, &hoods.tree, (&hoods.knn, hoods.kmax), rate, deal);
    let with_off = |off: &OffPoints| {
        let mut prep = data.clone();
        prep.centres.extend_from_slice(&off.centres);
        prep.values.extend(off_values(off, &data.points, &data.carrier, &data.norm));
        prep
    };
    let mut prep = with_off(&off);
    let off_count = off.side.len();
    let first = solve_serial(&prep, &k, SolverKind::Householder);
    // the ray test turns patches before the blob search; their off points change side in place
    let spacing = rays::spacing(&data.centres, &hoods.knn, hoods.kmax);
    let verdicts =
        rays::verdicts(&Solo, &first, &data.carrier, &data.centres, &normals, &hoods.tree, &spacing);
    let before = normals.clone();
    let turned = rays::turn_doubtful_patches(&data.centres, &mut normals, &hoods.knn, hoods.kmax, &verdicts);
    if turned.turned > 0 {
        for (side, &i) in off.side.iter_mut().zip(&off.source) {
            if (0..3).map(|d| before[i][d] * normals[i][d]).sum::<f64>() < 0.0 {
                *side = -*side;
            }
        }
        prep = with_off(&off);
    }
    // the blob search on the first fit (the default margin 0.05)
    let lattice = Lattice::of_fit(&data.box_lo, &data.box_hi, 0.05, &data.norm);
    let sampled = sample(&Solo, &lattice, &data.carrier, &first);
    let search = Search::new(&Solo, &lattice, &sampled, &data.centres, &normals, &hoods.tree);
    FirstFit { k, data, prep, off_count, first, turned, lattice, search, normals, hoods, off }
}

/// What the serial oracle made and decided.
struct Oracle {
    model: Model,
    /// The off points' count.
    off_count: usize,
    /// What the ray test turned.
    rays: RayCheck,
    /// Which clearance the choice kept (None: no choice made).
    kept_narrow: Option<bool>,
    /// The blob search's second round: its pins and whether its fit was kept (None: no round).
    second_round: Option<(usize, bool)>,
    /// The turns by unsupported surface.
    turns: TurnCheck,
    /// Whether the side vote's try was made (`--orient-side try`; else `off`).
    side_try: bool,
    /// The outside off points after the turns as the report states them (None: none placed).
    outside: Option<String>,
    /// The outside off points among the model's centres (0: none kept).
    outside_kept: usize,
    /// The off points at the mouths of holes, last but the cap points among the model's centres
    /// (0: none placed).
    mouth: usize,
    /// The cap points after them (`--cap-bulge`), last.
    caps: usize,
}

/// The default fit of `read` (the kernel r, the default carrier) made serially from the
/// library's steps: orientation, off points, the first fit, the ray test, the blob search and
/// the second fit, or with `choose` the choice between two second fits (`--blob-choice on`) and
/// the blob search's second round, and with `turns` the turns by unsupported surface and the
/// outside off points and the off points at the mouths of holes after them (`--orient-turns
/// on`, `--outside-points on`, `--mouth-points on`, which run where
/// the binary kept its first factor: the projected Cholesky), and with `side_try` the side
/// vote's turns tried together before the turns' patches (`--orient-side try`; without it
/// `off`). No step is limited by memory: the samples are small.
fn serial_offsurface(read: &[f64], rate: OffRates, choose: bool, turns: bool, side_try: bool) -> Oracle {
    let FirstFit { k, data, prep, off_count, first, turned, lattice, search, mut normals, hoods, mut off } =
        first_fit(read, rate);
    // the second fit; with `choose`, where the wide and the narrow clearance pin different nodes,
    // the second fit of each and the one with less unsupported surface kept
    let support = DataSupport::new(&data.centres, choice::FACTOR);
    let wide = search.blobs(&lattice, CLEARANCE);
    let narrow = search.blobs(&lattice, choice::NARROW * support.spacing);
    println!(
        "{} blob points (narrow clearance {}), {} detached regions; rays {turned:?}",
        wide.source.len(),
        narrow.source.len(),
        wide.regions
    );
    let fit_with = |blobs: &Blobs| {
        let system = second_system(&prep, &data, blobs);
        if blobs.source.is_empty() && turned.turned == 0 {
            return (first.clone(), system);
        }
        (solve_serial(&system, &k, SolverKind::Householder), system)
    };
    let winding = |at: &[[f64; 3]]| winding_numbers(&Solo, at, &data.centres, &normals, search.areas());
    let share = |values: &[f64]| unsupported_share(&lattice, values, &support, winding).0;
    let ((mut spline, mut system), kept_narrow) = if !choose || narrow.centres == wide.centres {
        (fit_with(&wide), None)
    } else {
        let (a, b) = (fit_with(&wide), fit_with(&narrow));
        let sampled = |s: &Spline| sample(&Solo, &lattice, &data.carrier, s);
        let narrower = share(&sampled(&b.0)) < share(&sampled(&a.0));
        (if narrower { b } else { a }, Some(narrower))
    };
    // the second round, where the clearance kept pinned a sparse sample of its spurious nodes
    // (the choice on): the nodes in open space of the kept fit pinned too, that fit kept where it
    // leaves no more data points without solid and less surface unsupported
    let (kept, clearance) = match kept_narrow {
        Some(true) => (&narrow, choice::NARROW * support.spacing),
        _ => (&wide, CLEARANCE),
    };
    let mut second_round = None;
    if choose && kept.found > SECOND_ROUND_FROM * kept.source.len() {
        let values = sample(&Solo, &lattice, &data.carrier, &spline);
        let again = search.again(&Solo, &lattice, &values, &data.centres, &normals, &hoods.tree);
        let more = again.open_blobs(&lattice, clearance);
        if !more.source.is_empty() {
            let tried = second_system(&system, &data, &more);
            let tried_spline = solve_serial(&tried, &k, SolverKind::Householder);
            let tried_values = sample(&Solo, &lattice, &data.carrier, &tried_spline);
            let without = |v: &[f64]| points_without_solid(&lattice, v, &data.centres);
            let kept = without(&tried_values) <= without(&values) && share(&tried_values) < share(&values);
            println!("second round: {} points in open space, kept {kept}", more.source.len());
            if kept {
                (system, spline) = (tried, tried_spline);
            }
            second_round = Some((more.source.len(), kept));
        }
    }
    // the solid given back where pins were added: the nodes inside the data's surface of the
    // points that lost their solid, where there are RESTORE_FROM, and the paths to the parts
    // lost whole, with the first fit's values; kept where fewer points are left without solid,
    // whose values the turns then start from (sampled again around each node alone)
    let mut values = sample(&Solo, &lattice, &data.carrier, &spline);
    if system.centres.len() > prep.centres.len() {
        let first_values = sample(&Solo, &lattice, &data.carrier, &first);
        let lost = lost_solid(&lattice, &first_values, &values, &data.centres);
        let at: Vec<[f64; 3]> = lost.iter().map(|&i| lattice.node(i)).collect();
        let w = winding_numbers(&Solo, &at, &data.centres, &normals, search.areas());
        let inside: Vec<usize> = lost.iter().zip(&w).filter(|(_, &w)| w >= INSIDE).map(|(&i, _)| i).collect();
        let mut nodes = if inside.len() >= RESTORE_FROM { inside } else { Vec::new() };
        nodes.extend(paths_to_solid(&lattice, &first_values, &values, &data.centres));
        // a node the search pinned keeps its pin (a second centre there is a singular system)
        let key = |q: &[f64]| [q[0].to_bits(), q[1].to_bits(), q[2].to_bits()];
        let pinned: std::collections::HashSet<[u64; 3]> = system.centres.chunks_exact(3).map(key).collect();
        nodes.retain(|&i| !pinned.contains(&key(&lattice.node(i))));
        nodes.sort_unstable();
        nodes.dedup();
        if !nodes.is_empty() {
            let mut tried = system.clone();
            for &i in &nodes {
                let q = lattice.node(i);
                tried.centres.extend_from_slice(&q);
                tried.values.push(data.carrier.eval(&data.norm.undo(&q)) - first_values[i]);
            }
            let tried_spline = solve_serial(&tried, &k, SolverKind::Householder);
            let mut tried_values = values.clone();
            for &i in &nodes {
                let window = lattice.around(lattice.node(i), lattice.node(i), 0.0);
                sample_window(&Solo, &lattice, &window, (&data.carrier, &tried_spline), &mut tried_values);
            }
            let without = |v: &[f64]| points_without_solid(&lattice, v, &data.centres);
            let kept = without(&tried_values) < without(&values);
            println!("solid given back at {} nodes: kept {kept}", nodes.len());
            if kept {
                (system, spline, values) = (tried, tried_spline, tried_values);
            }
        }
    }
    let mut check = TurnCheck::default();
    let (mut outside, mut outside_kept, mut mouth_count, mut caps_count) = (None, 0, 0, 0);
    if turns {
        // each candidate patch turned in turn: its normals and off points change side, the same
        // centres are solved for the new values, the lattice is sampled again around the patch
        let mut far = choice::unsupported_crossings(&lattice, &values, &support).0;
        let knn = (&hoods.knn[..], hoods.kmax);
        let mut candidates = turns::candidates(&data.centres, &normals, knn, &hoods.tree, &far);
        let patches = candidates.len();
        // then the groups of points facing a sheet, by the unsupported crossings in their windows
        let in_window = |c: &turns::Candidate| {
            choice::unsupported_in_window(&lattice, &values, &support, &c.window(&lattice))
        };
        let facing = turns::facing_candidates(
            &data.centres,
            &normals,
            knn,
            (&candidates, &off.source),
            in_window,
            far.len(),
        );
        candidates.extend(facing);
        // every candidate is solved here: the binary passes over only those that cannot gain
        (check.candidates, check.tried) = (candidates.len(), candidates.len());
        (check.before, check.facing) = (far.len(), candidates.len() - patches);
        // the side vote's turns, all its patches one candidate, tried first and kept where the
        // unsupported crossings fall at all
        let side = side_try.then(|| turns::side_candidate(&data.centres, &normals, knn)).flatten();
        let sides = usize::from(side.is_some());
        if let Some((candidate, patches)) = side {
            let points = candidate.members.len();
            check.side = Some(SideTry { patches, points, ..Default::default() });
            candidates.insert(0, candidate);
        }
        for (number, candidate) in candidates.into_iter().enumerate() {
            let (vote, number) = (number < sides, number.saturating_sub(sides));
            let (mut turned_normals, mut turned_off) = (normals.clone(), off.clone());
            candidate.members.iter().for_each(|&i| turned_normals[i] = normals[i].map(|v| -v));
            for (side, i) in turned_off.side.iter_mut().zip(&off.source) {
                if candidate.members.contains(i) {
                    *side = -*side;
                }
            }
            let mut tried = system.clone();
            let nd = data.values.len();
            let new_values = off_values(&turned_off, &data.points, &data.carrier, &data.norm);
            tried.values[nd..nd + new_values.len()].copy_from_slice(&new_values);
            let tried_spline = solve_serial(&tried, &k, SolverKind::Householder);
            let mut tried_values = values.clone();
            let window = candidate.window(&lattice);
            sample_window(&Solo, &lattice, &window, (&data.carrier, &tried_spline), &mut tried_values);
            let after = choice::unsupported_crossings(&lattice, &tried_values, &support).0;
            // the unsupported crossings in open space within the window, before and after
            let open = || {
                let count = |values: &[f64], normals: &[[f64; 3]]| {
                    let data = (&data.centres[..], normals, search.areas());
                    turns::open_space_crossings(&Solo, (&lattice, &window), values, &support, data)
                };
                (count(&values, &normals), count(&tried_values, &turned_normals))
            };
            // a group facing a sheet is kept by open space alone
            let kept = if vote {
                let kept = turns::keeps_side(far.len(), after.len());
                if let Some(side) = check.side.as_mut() {
                    (side.before, side.after, side.kept) = (far.len(), after.len(), kept);
                }
                kept.then_some(false)
            } else if number >= patches {
                turns::keeps_group(far.len(), after.len(), open).then_some(true)
            } else {
                turns::keeps_by(far.len(), after.len(), open)
            };
            // either, where no count keeps it, as the smoother spline
            let energy =
                |spline: &Spline, system: &Prepared| turns::bending_energy(&spline.weights, &system.values);
            let smoother = !vote
                && kept.is_none()
                && turns::keeps_smoother(
                    far.len(),
                    after.len(),
                    (energy(&spline, &system), energy(&tried_spline, &tried)),
                );
            if let Some(by_open_space) = kept.or(smoother.then_some(false)) {
                (normals, off, system, spline) = (turned_normals, turned_off, tried, tried_spline);
                (values, far) = (tried_values, after);
                if vote {
                    continue;
                }
                check.turned += 1;
                check.turned_points += candidate.members.len();
                check.by_open_space += usize::from(by_open_space);
                check.smoother += usize::from(smoother);
                check.facing_turned += usize::from(number >= patches);
            }
        }
        check.after = far.len();
        // last, an outside off point for each data point without one nearest to an unsupported
        // crossing in open space, the fit with them kept where the crossings fall by the gain
        let winding = winding_numbers(&Solo, &far, &data.centres, &normals, search.areas());
        let hits = outside::charged(&far, &winding, &hoods.tree, normals.len(), ..OPEN_SPACE);
        let extra = outside::outside_points(&data.centres, &normals, &hoods.tree, &off, &hits);
        // then both sides of the points nearest to enough crossings in the mouths of holes,
        // charged by the same crossings, the fit with them kept
        let hits = outside::charged(&far, &winding, &hoods.tree, normals.len(), outside::MOUTH);
        let around = (&hoods.tree, (&hoods.knn[..], hoods.kmax));
        let (mouth, _) = outside::mouth_points(&data.centres, &normals, around, &off, &hits);
        if !extra.side.is_empty() {
            let mut tried = system.clone();
            tried.centres.extend_from_slice(&extra.centres);
            tried.values.extend(off_values(&extra, &data.points, &data.carrier, &data.norm));
            let tried_spline = solve_serial(&tried, &k, SolverKind::Householder);
            // sampled again around the outside points alone
            let around = (&far[..], &winding[..], OPEN_SPACE);
            let nodes = outside::window_nodes(&lattice, &data.centres, &hoods.tree, around, &extra);
            let mut tried_values = values.clone();
            sample_nodes(&Solo, &lattice, &nodes, (&data.carrier, &tried_spline), &mut tried_values);
            let after = choice::unsupported_crossings(&lattice, &tried_values, &support).0.len();
            let kept = turns::gains(far.len(), after);
            let open = winding.iter().filter(|&&w| w < OPEN_SPACE).count();
            let line = format!(
                "outside points: {} for {open} crossings in open space, unsupported crossings {} -> {after}: {}",
                extra.side.len(),
                far.len(),
                if kept { "kept" } else { "dropped" }
            );
            println!("{line}");
            outside = Some(line);
            if kept {
                (system, spline) = (tried, tried_spline);
                outside_kept = extra.side.len();
            }
        }
        if !mouth.side.is_empty() {
            system.centres.extend_from_slice(&mouth.centres);
            let slope = volspline::surface::outside::MOUTH_SLOPE;
            system.values.extend(off_values_sloped(&mouth, &data.points, &data.carrier, &data.norm, slope));
            // with them the cap points at the same crossings nearest to the rim points held
            let mut rim = vec![false; normals.len()];
            mouth.source.iter().for_each(|&i| rim[i] = true);
            let at = (&normals[..], &hoods.tree);
            let caps = outside::cap_points((&far, &winding), at, &rim, support.spacing, outside::CAP_BULGE);
            system.centres.extend_from_slice(&caps.centres);
            system.values.extend(off_values(&caps, &data.points, &data.carrier, &data.norm));
            spline = solve_serial(&system, &k, SolverKind::Householder);
            (mouth_count, caps_count) = (mouth.side.len(), caps.side.len());
        }
    }
    let model =
        Model { carrier: data.carrier.clone(), spline, coarse: Vec::new(), provenance: Default::default() };
    Oracle {
        model,
        off_count,
        rays: turned,
        kept_narrow,
        second_round,
        turns: check,
        side_try,
        outside,
        outside_kept,
        mouth: mouth_count,
        caps: caps_count,
    }
}

/// The second system: the first one's centres and values (`prep`) with the constraint points of
/// `blobs` appended (`data` the data alone).
fn second_system(prep: &Prepared, data: &Prepared, blobs: &Blobs) -> Prepared {
    let mut out = prep.clone();
    out.centres.extend_from_slice(&blobs.centres);
    out.values.extend(blob_values(blobs, &data.points, &data.carrier, &data.norm));
    out
}

/// Fits `input` on 1, 2 and 3 ranks with `solver` (the off-point options `rates` and the further
/// options `extra`) and compares
/// with the serial `oracle` (centres exactly, weights and grid values to 1e-9). With the projected
/// Cholesky the second fit must have bordered the first fit's factor.
fn fits_match_the_oracle(
    dir: &Path,
    input: &Path,
    oracle: &Oracle,
    solver: &str,
    rates: &[&str],
    extra: &[&str],
) -> Vec<String> {
    let (off_count, outside, side_try) = (oracle.off_count, &oracle.outside, oracle.side_try);
    let oracle = &oracle.model;
    let mut reports = Vec::new();
    for ranks in [1, 2, 3] {
        let p = dir.join(format!("r{ranks}"));
        let p = p.to_str().unwrap();
        let args = [
            "fit",
            input.to_str().unwrap(),
            "--out",
            p,
            "--solver",
            solver,
            "--grid",
            "16",
            "--panel",
            "16",
            "--orient-side",
            if side_try { "try" } else { "off" },
        ];
        let text = common::run_ok(ranks, &[&args[..], &BALL, rates, extra].concat());
        assert!(text.contains(&format!("{off_count} off-surface points")), "{text}");
        if solver == "cholesky" {
            assert!(text.contains("second fit: the first fit's factor"), "{text}");
        }
        if let Some(line) = outside {
            assert!(text.contains(line), "{ranks} ranks: not \"{line}\" in {text}");
        }
        let model = read_model(Path::new(&format!("{p}.model.h5"))).unwrap();
        assert_eq!(model.spline.centres, oracle.spline.centres, "{ranks} ranks: other constraint points");
        let dw = common::rel_diff(&model.spline.weights, &oracle.spline.weights);
        let dc = common::rel_diff(&model.spline.poly, &oracle.spline.poly);
        assert!(dw < 1e-9 && dc < 1e-9, "{ranks} ranks: weights {dw:e}, poly {dc:e}");
        let dv = common::volume_diff(Path::new(&format!("{p}.hdf")), oracle);
        assert!(dv < 1e-9, "{ranks} ranks: grid values differ by {dv:e}");
        reports.push(text);
    }
    reports
}

/// `n` area-uniform samples (seed `seed` of the tests' sampler) of the mesh at `mesh`, written to
/// `file` in a new temporary folder `name`: the folder and the file.
fn sampled_input(name: &str, file: &str, mesh: &str, (n, seed): (usize, u64)) -> (common::TempDir, PathBuf) {
    let dir = common::temp_dir(name);
    let input = dir.join(file);
    common::write_xyz(&input, &area_samples(&common::load_mesh(Path::new(mesh)), n, seed));
    (dir, input)
}

/// The points of `input` as the binary reads them.
fn read_back(input: &Path) -> Vec<f64> {
    volspline::io::points::read_points(input).unwrap().points.iter().flatten().copied().collect()
}

#[test]
fn offsurface_fits_on_one_two_and_three_ranks_match_the_serial_oracle() {
    let dir = common::temp_dir("offsurface-oracle");
    let input = dir.join("bunny506.xyz");
    common::write_xyz(&input, &common::bunny_subset(10, 0));
    // a system of about 700 rows, solved by Householder QR: the turns' tries are fresh fits
    let oracle = serial_offsurface(&read_back(&input), UNIFORM_DEALT, false, true, false);
    assert_eq!(oracle.off_count, 197);
    fits_match_the_oracle(&dir, &input, &oracle, "householder", &UNIFORM, &["--blob-choice", "off"]);
}

/// Cow samples (the tests' sampler: points, seed) on which the ray test turns patches and then
/// the turns by unsupported surface turn one, dealt among neighbours (measured: see the test
/// below; of seeds 1-12, seeds 1, 3, 4 and 10 do both).
const RAYS_COW: (usize, u64) = (2000, 10);

/// The patches turned by the ray test and then by the unsupported surface: the same on 1, 2 and 3
/// ranks as in the serial oracle.
#[test]
fn patches_turned_by_the_ray_test_are_the_same_on_one_two_and_three_ranks() {
    let (dir, input) = sampled_input("rays-oracle", "cow.xyz", common::COW, RAYS_COW);
    let oracle = serial_offsurface(&read_back(&input), UNIFORM_DEALT, false, true, false);
    let (turned, turns) = (&oracle.rays, &oracle.turns);
    // measured: 3 patches (13 points) turned
    assert!(turned.turned > 0, "{turned:?}");
    // then the turns by unsupported surface turn a patch too (measured: 1 of 3 tried, 7 points,
    // 389 -> 352 unsupported crossings), each try solved with the second fit's bordered factor
    assert!(turns.turned > 0 && turns.after < turns.before, "{turns:?}");
    // the second fit borders the first's factor (its off points changed side, blob points added)
    let reports = fits_match_the_oracle(&dir, &input, &oracle, "cholesky", &UNIFORM, &NO_CHOICE);
    // the tries were the kept fit's solution plus columns of one solve of the candidates'
    // changes, and the turns they kept are those of the oracle's separate solves
    for text in &reports {
        let tried = text.split_once("; turns: ").and_then(|(_, t)| t.split(' ').nth(2)).unwrap();
        let together = format!(", {tried} tried by one solve of the candidates' changes");
        assert!(text.contains(&together), "not \"{together}\" in {text}");
    }
}

/// Cow samples on which the wide and the narrow clearance of the blob search pin different nodes
/// and the narrow one leaves less unsupported surface, with the default's rates and with those
/// of `UNIFORM` (measured: see the test below; of seeds 1-12 at 2000 points, the choice keeps
/// the narrow fit on 11, with the turns off, and on this one it is nearest the cow).
const CHOICE_COW: (usize, u64) = (2000, 8);

#[test]
fn the_clearance_choice_is_the_same_on_one_two_and_three_ranks() {
    let (dir, input) = sampled_input("choice-oracle", "cow.xyz", common::COW, (CHOICE_COW.0, CHOICE_COW.1));
    let oracle = serial_offsurface(&read_back(&input), UNIFORM_DEALT, true, true, false);
    assert_eq!(oracle.kept_narrow, Some(true));
    // the default: the choice on, the off points dealt among neighbours
    fits_match_the_oracle(&dir, &input, &oracle, "cholesky", &UNIFORM, &[]);
}

#[test]
fn the_clearance_choice_keeps_the_fit_nearer_the_cow() {
    // the set of the test above with the default options (grid 64, one rank): the wide
    // clearance of rule 2 leaves bulges beside the legs, the narrow one pins them (99 and 122
    // blob points); the fit with less surface farther than twice the median spacing from every
    // data point is kept. Measured: mesh -> cow rms 0.253 -> 0.210 % of the diagonal, vertices
    // beyond 2 % 0.22 -> 0.00 %; unsupported surface on the lattice 4.3 % (wide) against 4.2 %
    // (narrow). No second round runs on either. (Before rule 3 took the winding number, 1000
    // samples, seed 2, went 0.513 -> 0.454; rule 3 now removes most of what the narrow
    // clearance did there)
    let truth = common::load_mesh(Path::new(common::COW));
    let pts = area_samples(&truth, CHOICE_COW.0, CHOICE_COW.1);
    // the turns off in both: what is compared is the choice alone
    let (off, _, off_line) = fit_mesh("cow-choice-off", &pts, "64", &[&NO_CHOICE[..], &NO_TURNS].concat());
    let (on, _, on_line) = fit_mesh("cow-choice-on", &pts, "64", &NO_TURNS);
    let ((rms_off, far_off), (rms_on, far_on)) = (mesh_to_truth(&truth, &off), mesh_to_truth(&truth, &on));
    println!("off: {off_line}\n  rms {rms_off:.5}, far {far_off:.4}\non: {on_line}\n  rms {rms_on:.5}, far {far_on:.4}");
    assert!(!off_line.contains("clearance:"), "{off_line}");
    assert!(on_line.contains("narrow kept") && on_line.contains("fitted three times"), "{on_line}");
    // the shares in the report: the kept one is the smaller
    let share = |key: &str| -> f64 {
        let tail = &on_line[on_line.find(key).unwrap() + key.len()..];
        let num = tail.split_once(" points, ").unwrap().1.split(' ').next().unwrap();
        num.parse().unwrap()
    };
    let (wide, narrow) = (share("clearance: wide "), share("narrow "));
    assert!(narrow < wide, "{on_line}");
    assert!(
        rms_on < 0.96 * rms_off && far_on <= far_off,
        "mesh -> cow rms {rms_off} -> {rms_on}, far {far_off} -> {far_on}"
    );
}

#[test]
fn compactly_supported_fits_take_the_off_surface_points_at_level_zero_on_one_and_two_ranks() {
    let dir = common::temp_dir("offsurface-csrbf");
    let all = common::bunny();
    let quarter: Vec<f64> = all.chunks_exact(3).step_by(4).flatten().copied().collect();
    let input = dir.join("quarter.xyz");
    common::write_xyz(&input, &quarter);
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);
    let mut models = Vec::new();
    // cholesky on one rank, MUMPS on two; the default support
    for (ranks, solver) in [(1, "cholesky"), (2, "mumps")] {
        let p = dir.join(format!("c{ranks}"));
        let args = [
            "fit",
            input.to_str().unwrap(),
            "--out",
            p.to_str().unwrap(),
            "--method",
            "csrbf",
            "--sparse-solver",
            solver,
            "--grid",
            "48",
        ];
        common::run_ok(ranks, &[&args[..], &UNIFORM, &BALL].concat());
        let model = read_model(&dir.join(format!("c{ranks}.model.h5"))).unwrap();
        // level 0: all 1263 data points (fewer than --coarse-points) and 499 off-surface points
        // (0.4 per point in expectation, UNIFORM, dealt among neighbours), then 5 off points at
        // the rims of the holes in the bunny's base (9 without the side vote's try in step 7, 14
        // before rim points at folds were left out); level 1: the data points
        assert_eq!(model.coarse.len(), 1);
        assert_eq!(model.coarse[0].len(), 1263 + 499 + 5);
        assert_eq!(model.spline.len(), 1263);
        let mesh = common::load_mesh(&dir.join(format!("c{ranks}.ply")));
        let (mean, p95, max) = common::distance_stats(point_mesh_distances(&truth, &mesh.vertices), diag);
        println!("csrbf offsurface on {ranks} ranks: mesh -> bunny mean {mean:.5} p95 {p95:.5} max {max:.5}");
        // measured: mean 0.0023, p95 0.0075 and one component (the plain carrier method with
        // wendland2 of support 0.6: mean 0.031, 36 % of the vertices beyond 2 % of the diagonal)
        assert_eq!(connected_components(&mesh), 1);
        assert!(mean < 0.003 && p95 < 0.01, "mesh -> bunny mean {mean}, p95 {p95}");
        models.push(model);
    }
    // level 1 interpolates what level 0 leaves at the data, here rounding (level 0 holds every
    // point): its coefficients are compared on the scale of level 0's
    let coef = |s: &volspline::spline::Spline| [s.weights.clone(), s.poly.clone()].concat();
    let scale = coef(&models[0].coarse[0]).iter().fold(0.0f64, |m, c| m.max(c.abs()));
    for (l, (a, b)) in models[1].levels().zip(models[0].levels()).enumerate() {
        let d = coef(a).iter().zip(&coef(b)).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale;
        assert!(d < 1e-8, "MUMPS on 2 ranks vs cholesky on 1: level {l}'s coefficients differ by {d:e}");
    }
}

/// The connected component of every vertex of `mesh` (by shared triangles).
fn vertex_components(mesh: &volspline::mesh::TriMesh) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..mesh.vertices.len()).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for t in &mesh.triangles {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, t[0] as usize), root(&mut parent, t[k] as usize));
            parent[a] = b;
        }
    }
    (0..parent.len()).map(|i| root(&mut parent, i)).collect()
}

#[test]
fn the_cow_has_no_spurious_blobs() {
    // 1000 points uniform over the cow's surface, unoriented: the first off-surface fit is
    // positive in empty space beside the legs and the head and bulges out where the orientation
    // errs; the second fit pins the unsupported regions outside. Measured on this set (grid 64):
    // one fit (before) mesh -> cow rms 3.6 % of the diagonal, 22 % of the vertices beyond 2 %,
    // four components; with the second fit 1.2 % and 6.8 %, three: the body and two small
    // pieces of the thin legs (no vertex of either beyond 2 %).
    let truth = common::load_mesh(Path::new(common::COW));
    let pts = area_samples(&truth, 1000, 7);
    let (mesh, h, surface) = fit_mesh("cow-blobs", &pts, "64", &[]);
    let all: Vec<f64> = truth.vertices.iter().flatten().copied().collect();
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);
    let d = point_mesh_distances(&truth, &mesh.vertices);
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt() / diag;
    let far = d.iter().filter(|&&x| x > 0.02 * diag).count() as f64 / d.len() as f64;
    println!("cow 1000 points: {surface}; mesh -> cow rms {rms:.5}, far {far:.4}, h {h}");
    assert!(surface.contains("blobs: ") && !surface.contains("blobs: none"), "{surface}");
    assert!(rms < 0.015 && far < 0.1, "mesh -> cow rms {rms}, far {far}");
    // no component is a blob: each lies mostly on the true surface
    let label = vertex_components(&mesh);
    let mut per: std::collections::BTreeMap<usize, (usize, usize)> = Default::default();
    for (l, dist) in label.iter().zip(&d) {
        let e = per.entry(*l).or_default();
        e.0 += 1;
        e.1 += usize::from(*dist > 0.02 * diag);
    }
    println!("components (vertices, beyond 2 %): {:?}", per.values().collect::<Vec<_>>());
    for (count, beyond) in per.values() {
        assert!(2 * beyond < *count, "a component of {count} vertices, {beyond} beyond 2 % of the diagonal");
    }
}

/// Fits `tests/data/NAME.xyz` (`n` points, a sample of the surface benchmark) with the default
/// method on grid 64 and returns the mesh -> truth rms and far fraction against the mesh at
/// `truth` (see [`mesh_to_truth`]) and the surface line of the report, which it prints; `extra`
/// are further options.
fn fit_benchmark_sample(name: &str, n: usize, truth: &str, extra: &[&str]) -> (f64, f64, String) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(format!("{name}.xyz"));
    let pts: Vec<f64> =
        volspline::io::points::read_points(&path).unwrap().points.into_iter().flatten().collect();
    assert_eq!(pts.len(), 3 * n, "{}", path.display());
    fit_to_truth(name, &pts, &common::load_mesh(Path::new(truth)), extra)
}

/// Fits `pts` with the default surface method and `extra` (grid 64) and returns the mesh ->
/// `truth` rms and far fraction ([`mesh_to_truth`]) and the surface line of the report.
fn fit_to_truth(
    name: &str,
    pts: &[f64],
    truth: &volspline::mesh::TriMesh,
    extra: &[&str],
) -> (f64, f64, String) {
    let (mesh, _, surface) = fit_mesh(name, pts, "64", extra);
    let (rms, far) = mesh_to_truth(truth, &mesh);
    println!("{name}: {surface}\n  mesh -> truth rms {rms:.5}, far {far:.4}");
    (rms, far, surface)
}

#[test]
fn off_points_dealt_among_neighbours_give_the_same_solid_for_any_order_of_the_cloud_and_ranks() {
    // the cow at 1000 points with a hole (tests/data/cow-1000-open.xyz, 896 points, a sample of
    // the surface benchmark), whose figures moved most with the order of its points under the
    // default dealing by index (mesh -> truth 0.50 -> 1.27 % of the diagonal): with
    // --off-deal neighbours, read backwards on 2 ranks and in a scrambled order on 3 it gives
    // the volume of the file order on 1, to rounding; by index the scrambled order gives another
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-1000-open.xyz");
    let read = volspline::io::points::read_points(&path).unwrap().points;
    let n = read.len();
    assert_eq!(n, 896);
    let volume = |name: &str, ranks: usize, deal: &str, order: &dyn Fn(usize) -> usize| {
        let pts: Vec<f64> = (0..n).flat_map(|i| read[order(i)]).collect();
        let dir = common::temp_dir(name);
        let input = dir.join("p.xyz");
        common::write_xyz(&input, &pts);
        let prefix = dir.join("s");
        let (input, prefix) = (input.to_str().unwrap(), prefix.to_str().unwrap());
        let args = ["fit", input, "--out", prefix, "--grid", "48", "--no-preview", "--off-deal", deal];
        let text = common::run_ok(ranks, &args);
        let surface = text.lines().find(|l| l.contains("surface ")).unwrap_or("").to_string();
        (read_image(&dir.join("s.hdf"), "f").unwrap().1, surface)
    };
    // i -> 389 i mod 896 scrambles them (389 is prime to 896)
    let scrambled = |i: usize| 389 * i % n;
    let (a, sa) = volume("order-file", 1, "neighbours", &|i| i);
    let (b, sb) = volume("order-backwards", 2, "neighbours", &|i| n - 1 - i);
    let (c, sc) = volume("order-scrambled", 3, "neighbours", &scrambled);
    println!("file order: {sa}\nbackwards: {sb}\nscrambled: {sc}");
    let differ = |other: &[f64]| {
        let signs = a.iter().zip(other).filter(|(x, y)| (**x >= 0.0) != (**y >= 0.0)).count();
        (common::rel_diff(other, &a), signs)
    };
    // (to rounding: measured 2.0e-6 backwards since the hole's 2 cap points were added)
    for (name, other) in [("backwards", &b), ("scrambled", &c)] {
        let (d, signs) = differ(other);
        assert!(d < 1e-5 && signs == 0, "{name}: volume differs by {d}, {signs} nodes change sign");
    }
    let (x, _) = volume("order-index-file", 2, "index", &|i| i);
    let (y, _) = volume("order-index-scrambled", 2, "index", &scrambled);
    let d = common::rel_diff(&x, &y);
    assert!(d > 1e-3, "by index the scrambled order differs by only {d}");
}

/// Cow samples (the tests' sampler, 400 points) on which the floor of blob points matters (see
/// the test below; of seeds 1-16, N/4 = 100 pins instead of 200 gave a larger mesh -> cow rms
/// on seeds 4, 6, 7, 9, 12, 13, 14 and 16, by up to 0.63 % of the diagonal, and a smaller one on
/// 1, 2, 3, 5, 8, 10, 11 and 15, by up to 0.50 %, 0.08 % but on seed 5).
const FLOOR_COW: (usize, u64) = (400, 12);

#[test]
fn a_small_scan_gets_enough_pins_for_the_false_solid_beside_the_cow() {
    // the first fit grows false solid beside the cow. N/4 = 100 pins, taken by an even stride
    // from the spurious nodes, leave much of it: measured (grid 64) mesh ->
    // cow rms 0.73 % of the diagonal, 3.2 % of the vertices beyond 2 %; the floor of 200 pins
    // removes it: 0.50 %, 0.85 % (0.49 %, 0.78 % with the 2 outside points of step 8)
    let truth = common::load_mesh(Path::new(common::COW));
    let pts = area_samples(&truth, FLOOR_COW.0, FLOOR_COW.1);
    let (rms, far, surface) = fit_to_truth("cow-400-floor", &pts, &truth, &[]);
    let pins = volspline::surface::blobs::MIN_CAP;
    assert!(surface.contains(&format!("blobs: {pins} constraint points")), "{surface}");
    assert!(rms < 0.006 && far < 0.02, "mesh -> cow rms {rms}, far {far}");
    // its second round pins 3 nodes and leaves 3 more data points without solid: it is dropped
    // once the data points' cells alone are sampled, so no share is measured for it
    assert!(
        surface.contains("second round: 3 points in open space, data points without solid 11 -> 14: dropped"),
        "{surface}"
    );
}

#[test]
fn the_dipole_correction_leaves_the_flat_base_of_a_sparse_bunny_alone() {
    // 400 area-uniform samples of the bunny (tests/data/bunny-400.xyz, a sample of the surface
    // benchmark): the spectral orientation gets the flat base right, and the dense dipole field
    // used to flip it, 44 points in one patch, into the body; the blob search then pinned nodes
    // inside the body (its voters near the base saw them outside) and hollowed it out. Measured
    // (grid 64) mesh -> bunny rms 2.74 % of the diagonal, 25 % of the vertices beyond 2 %; with
    // only patches of at most 5 % of the points movable 1.27 %, 7.7 %
    let (rms, far, _) = fit_benchmark_sample("bunny-400", 400, common::BUNNY, &[]);
    assert!(rms < 0.018, "mesh -> bunny rms {rms}, far {far}");
}

/// Cow samples (the tests' sampler) on which the narrow clearance is kept and the blob search's
/// second round pins nodes in open space and keeps its fit (measured: see the tests below; of
/// the cow at 400 and 1000 points, with and without a hole, and the bunny with a hole, seeds
/// 1-12, eight rounds pinned nodes and five were kept).
const SECOND_ROUND_COW: (usize, u64) = (1000, 12);

#[test]
fn a_second_round_of_pins_removes_the_false_solid_the_first_left_under_the_cow() {
    // the clearance kept leaves most of the first fit's spurious nodes unpinned (the cap of N/4
    // pins), and the second fit keeps a sheet of false solid under the belly and between the
    // legs. The second round pins 68 nodes in open space and keeps its fit. Measured (grid 64)
    // mesh -> cow rms 0.99 % of the diagonal, 4.6 % of the vertices beyond 2 %, without it;
    // 0.29 % and 0.05 % with it
    let truth = common::load_mesh(Path::new(common::COW));
    let pts = area_samples(&truth, SECOND_ROUND_COW.0, SECOND_ROUND_COW.1);
    let (rms, far, surface) = fit_to_truth("cow-second-round", &pts, &truth, &[]);
    assert!(
        surface.contains("second round: 68 points in open space") && surface.contains(": kept"),
        "{surface}"
    );
    assert!(rms < 0.005 && far < 0.01, "mesh -> cow rms {rms}, far {far}");
}

#[test]
fn the_second_round_of_pins_is_the_same_on_one_two_and_three_ranks() {
    let (dir, input) = sampled_input("second-round-oracle", "cow.xyz", common::COW, SECOND_ROUND_COW);
    let oracle = serial_offsurface(&read_back(&input), DEFAULT_DEALT, true, true, false);
    // measured: the narrow clearance kept, 68 nodes pinned by the round, its fit kept
    assert_eq!((oracle.kept_narrow, oracle.second_round), (Some(true), Some((68, true))));
    // the default options
    fits_match_the_oracle(&dir, &input, &oracle, "cholesky", &DEFAULT_RATES, &[]);
}

/// The cow, the points of `tests/data/NAME.xyz` (a sample of the cow from the surface benchmark)
/// and the cow's bounding-box diagonal.
fn cow_sample(name: &str) -> (volspline::mesh::TriMesh, Vec<f64>, f64) {
    let truth = common::load_mesh(Path::new(common::COW));
    let pts: Vec<f64> = volspline::io::points::read_points(&sample_path(name))
        .unwrap()
        .points
        .into_iter()
        .flatten()
        .collect();
    let all: Vec<f64> = truth.vertices.iter().flatten().copied().collect();
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    (truth, pts, volspline::spline::hygiene::diagonal(&lo, &hi))
}

/// The file of the stored sample `name` (tests/data/NAME.xyz).
fn sample_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(format!("{name}.xyz"))
}

/// Truth -> mesh rms over the truth's vertices as a fraction of `diag`: how much of the truth
/// the mesh leaves out.
fn truth_to_mesh(truth: &volspline::mesh::TriMesh, mesh: &volspline::mesh::TriMesh, diag: f64) -> f64 {
    let d = point_mesh_distances(mesh, &truth.vertices);
    (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt() / diag
}

#[test]
fn solid_the_pins_took_from_a_thinly_sampled_leg_is_given_back() {
    // 400 area-uniform samples of the cow (tests/data/cow-400-seed6.xyz, seed 6 of the surface
    // benchmark): a front leg carries 3 of them. The first fit has it; the 200 pins of the blob
    // search, none near it, sink it below the lattice, and the mesh loses it. The nodes of the
    // points that lost their solid, inside the data's surface, get the first fit's values back.
    // Measured (grid 64): truth -> mesh rms 2.09 % of the diagonal without, 1.28 % with; mesh ->
    // truth 0.652 % and 0.714 %
    let (truth, pts, diag) = cow_sample("cow-400-seed6");
    let complete = |mesh: &volspline::mesh::TriMesh| truth_to_mesh(&truth, mesh, diag);
    let (off, _, off_line) =
        fit_mesh("cow-restore-off", &pts, "64", &[&["--restore-solid", "off"][..], &BY_INDEX].concat());
    let (on, _, on_line) = fit_mesh("cow-restore-on", &pts, "64", &BY_INDEX);
    let (t_off, t_on) = (complete(&off), complete(&on));
    let ((m_off, _), (m_on, _)) = (mesh_to_truth(&truth, &off), mesh_to_truth(&truth, &on));
    println!("without: {off_line}\n  truth -> mesh {t_off:.5}, mesh -> truth {m_off:.5}");
    println!("with: {on_line}\n  truth -> mesh {t_on:.5}, mesh -> truth {m_on:.5}");
    assert!(!off_line.contains("solid lost"), "{off_line}");
    assert!(on_line.contains("given back at") && on_line.contains(": kept"), "{on_line}");
    assert!(t_on < 0.016 && t_off > 0.019, "truth -> mesh {t_on} with, {t_off} without");
    assert!(m_on < 0.0075, "mesh -> truth {m_on} with ({m_off} without)");
}

#[test]
fn solid_given_back_along_the_first_fits_solid_is_the_same_on_one_two_and_three_ranks() {
    // the set of the test below with the default options: the narrow clearance kept (200 blob
    // points, no second round), 27 nodes given back inside the data and along the leg, kept
    // (with the wide clearance alone 26; dealt by index, the default before, 22 along the leg);
    // then 6 outside points for 46 unsupported crossings in open space, kept (333 -> 307)
    let dir = common::temp_dir("hoof-oracle");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-400-seed8.xyz");
    let oracle = serial_offsurface(&read_back(&input), DEFAULT_DEALT, true, true, false);
    assert_eq!((oracle.kept_narrow, oracle.second_round), (Some(true), None));
    assert_eq!(oracle.outside_kept, 6);
    let given = oracle.model.spline.centres.len() / 3 - 400 - oracle.off_count - 200 - oracle.outside_kept;
    assert_eq!(given, 27, "{given} nodes given back");
    fits_match_the_oracle(&dir, &input, &oracle, "cholesky", &DEFAULT_RATES, &[]);
}

#[test]
fn a_leg_sampled_at_its_hoof_alone_is_given_back_along_the_first_fits_solid() {
    // 400 area-uniform samples of the cow (tests/data/cow-400-seed8.xyz, seed 8 of the surface
    // benchmark): a front leg carries 2 of them, at its hoof, 13 % of the diagonal below the
    // nearest data point whose solid the pins leave. The first fit has the leg, the pins sink it
    // and the mesh loses it; the nodes of the hoof's points are not inside the data's surface,
    // and the solid is given back along the first fit's solid from them to the body. Measured
    // (grid 64): truth -> mesh rms 2.25 % of the diagonal without, 1.03 % with; mesh -> truth
    // 0.54 % and 0.57 % (0.61 % and 0.62 % before the outside points of step 8, kept in both
    // fits); the mesh's vertex nearest to a hoof's point at most 14.9 % of the diagonal away
    // without, 0.87 % with (22 nodes given back along the leg, 6 inside)
    let (truth, pts, diag) = cow_sample("cow-400-seed8");
    let complete = |mesh: &volspline::mesh::TriMesh| truth_to_mesh(&truth, mesh, diag);
    // the hoof: the data points below y = -0.5 on the side x > 0
    let hoof: Vec<[f64; 3]> = pts
        .chunks_exact(3)
        .filter(|p| p[1] < -0.5 && p[0] > 0.1 && p[2] > 0.1)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    assert_eq!(hoof.len(), 2, "{hoof:?}");
    let nearest = |mesh: &volspline::mesh::TriMesh| {
        hoof.iter()
            .map(|h| {
                mesh.vertices
                    .iter()
                    .map(|v| (0..3).map(|d| (v[d] - h[d]).powi(2)).sum::<f64>().sqrt())
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
            / diag
    };
    let (off, _, off_line) = fit_mesh("cow-hoof-off", &pts, "64", &["--restore-solid", "off"]);
    let (on, _, on_line) = fit_mesh("cow-hoof-on", &pts, "64", &[]);
    let (t_off, t_on) = (complete(&off), complete(&on));
    let ((m_off, _), (m_on, _)) = (mesh_to_truth(&truth, &off), mesh_to_truth(&truth, &on));
    let (h_off, h_on) = (nearest(&off), nearest(&on));
    println!("without: {off_line}\n  truth -> mesh {t_off:.5}, mesh -> truth {m_off:.5}, hoof {h_off:.4}");
    println!("with: {on_line}\n  truth -> mesh {t_on:.5}, mesh -> truth {m_on:.5}, hoof {h_on:.4}");
    assert!(on_line.contains("along the first fit's solid") && on_line.contains(": kept"), "{on_line}");
    assert!(t_on < 0.014 && t_off > 0.019, "truth -> mesh {t_on} with, {t_off} without");
    assert!(m_on < 0.0075, "mesh -> truth {m_on} with ({m_off} without)");
    assert!(h_on < 0.03 && h_off > 0.1, "hoof {h_on} with, {h_off} without");
}

/// The winding number of a triangle mesh at q: the solid angles of its triangles (Van Oosterom
/// and Strackee's formula) over 4 pi; +-1 inside a closed mesh, 0 outside.
fn mesh_winding(mesh: &volspline::mesh::TriMesh, q: [f64; 3]) -> f64 {
    let sub = |v: [f64; 3]| [v[0] - q[0], v[1] - q[1], v[2] - q[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let len = |a: [f64; 3]| dot(a, a).sqrt();
    let total: f64 = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| sub(mesh.vertices[i as usize]));
            let cross = [b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]];
            let (la, lb, lc) = (len(a), len(b), len(c));
            let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
            2.0 * dot(a, cross).atan2(den)
        })
        .sum();
    total / (4.0 * std::f64::consts::PI)
}

/// `n` area-uniform samples of `mesh` without those within 15 % of its diagonal of the sample
/// farthest along (1, 1, 1) in its normalised box: a scan with a hole.
fn with_hole(mesh: &volspline::mesh::TriMesh, n: usize, seed: u64) -> Vec<f64> {
    with_hole_centre(mesh, n, seed).0
}

/// [`with_hole`], the centre of the ball left out and its radius.
fn with_hole_centre(mesh: &volspline::mesh::TriMesh, n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, f64) {
    let pts = area_samples(mesh, n, seed);
    let all: Vec<f64> = mesh.vertices.iter().flatten().copied().collect();
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);
    let along = |p: &[f64]| (0..3).map(|d| (p[d] - lo[d]) / (hi[d] - lo[d])).sum::<f64>();
    let centre = pts.chunks_exact(3).max_by(|a, b| along(a).total_cmp(&along(b))).unwrap().to_vec();
    let r = 0.15 * diag;
    let kept = pts
        .chunks_exact(3)
        .filter(|p| (0..3).map(|d| (p[d] - centre[d]).powi(2)).sum::<f64>() > r * r)
        .flatten()
        .copied()
        .collect();
    (kept, centre, r)
}

/// Bunny samples with a hole on which the vote of the blob search's rule 2 finds nodes inside the
/// true bunny outside (measured: see the test below).
const HOLE_BUNNY: (usize, u64) = (1000, 5);

#[test]
fn the_lattice_sampled_in_single_precision_has_the_signs_of_double_precision_on_the_bunny() {
    // the blob search reads the first fit on its lattice from single-precision radial sums
    // (volspline::spline::sign_eval): on 400 bunny samples every node must have the sign the
    // double-precision spline gives it, and its value to a few digits; were the bound too small
    // near zero, or the weights' scaling wrong, nodes would change sign
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny-400.xyz");
    let f = first_fit(&read_back(&path), UNIFORM_DEALT);
    let sampled = sample(&Solo, &f.lattice, &f.data.carrier, &f.first);
    let ev = volspline::spline::Evaluator::new(&f.first);
    let (norm, nx) = (&f.data.norm, f.lattice.dims[0]);
    // about the module's bound 2 u W ((m + 4) R + 8 P): m = 32 products per lane, R and P about
    // 3.5 and 1.2 on this lattice (normalised coordinates)
    let w: f64 = f.first.weights.iter().map(|w| w.abs()).sum();
    let bound = 2.0 * w * (36.0 * 3.5 + 8.0 * 1.2) / (1u64 << 24) as f64;
    let (mut exact, mut near_zero, mut worst) = (vec![0.0; nx], 0, 0.0f64);
    for (row, got) in sampled.chunks_exact(nx).enumerate() {
        let q: Vec<[f64; 3]> = (0..nx).map(|x| norm.undo(&f.lattice.node(row * nx + x))).collect();
        let xs: Vec<f64> = q.iter().map(|p| p[0]).collect();
        ev.eval_row(&xs, q[0][1], q[0][2], &mut exact);
        for ((g, e), p) in got.iter().zip(&exact).zip(&q) {
            let want = f.data.carrier.eval(p) - e;
            assert_eq!(*g > 0.0, want > 0.0, "row {row}: {g} against {want}");
            assert!((g - want).abs() <= bound, "row {row}: {g} against {want}, bound {bound}");
            worst = worst.max((g - want).abs());
            near_zero += usize::from(g.to_bits() == want.to_bits() && want.abs() < 1.0);
        }
    }
    // the nodes near zero were summed again in double precision: the same bits
    println!("W {w:.4e}, bound {bound:.3e}, largest error {worst:.3e}, {near_zero} nodes near zero exact");
    assert!(near_zero > 0, "no node near zero summed again");
}

#[test]
fn the_winding_number_spares_the_nodes_under_a_hole_in_the_bunny() {
    // 1000 bunny samples less a ball of 15 % of the diagonal: the hole's rim points vote three
    // nodes inside the bunny outside (they lie above the rim's tangent planes); the winding
    // number of the oriented data encloses them, so they are spared, and no pin lies inside the
    // bunny. Measured: 909 points, 194 pins, 3 nodes spared, all inside (the mesh's own winding
    // number above 1/2); on seeds 1-16, 1-4 nodes were spared on 4 of them, 8 of 10 inside
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let pts = with_hole(&truth, HOLE_BUNNY.0, HOLE_BUNNY.1);
    let f = first_fit(&pts, UNIFORM_DEALT);
    let blobs = f.search.blobs(&f.lattice, CLEARANCE);
    let norm = &f.data.norm;
    let inside = |q: &[f64]| {
        mesh_winding(&truth, std::array::from_fn(|d| norm.centre[d] + norm.scale * q[d])).abs() > 0.5
    };
    let spared = blobs.spared.len() / 3;
    let spared_in = blobs.spared.chunks_exact(3).filter(|q| inside(q)).count();
    let pinned_in = blobs.centres.chunks_exact(3).filter(|q| inside(q)).count();
    println!(
        "{} points, {} pins ({pinned_in} inside), {spared} spared ({spared_in} inside)",
        pts.len() / 3,
        blobs.source.len()
    );
    assert!(
        spared >= 3 && spared_in == spared,
        "{spared} nodes spared, {spared_in} of them inside the bunny"
    );
    assert!(!blobs.source.is_empty() && pinned_in == 0, "{pinned_in} pins inside the bunny");
}

/// Cow samples with a hole (a ball of 15 % of the diagonal left out) on which the clearance
/// choice without its mouth rule would keep the narrow candidate, which hollows the cap.
const CAP_COW: (usize, u64) = (2000, 5);

#[test]
fn the_clearance_choice_keeps_the_cap_over_a_hole_in_the_cow() {
    // the narrow candidate pins nodes under the cap the first fit puts over the hole; counting
    // all unsupported surface it has the smaller share (the cap is unsupported too) and would be
    // kept; with the surface in the hole's mouth (data winding number 0.1-0.3) not counted, the
    // wide one is. Measured: shares 0.1413 (wide) and 0.1322 (narrow) without the mouth rule,
    // 0.0865 and 0.0890 with it; of the 372 lattice nodes inside the true cow within the hole's
    // ball, 12.9 % are outside the wide fit's solid, 23.7 % outside the narrow one's (48.9 % with
    // rule 2's winding threshold at 1/3, which left more pins under the cap). Over seeds
    // 1-10, with the off points dealt by index (the default before), the rule turned the choice
    // on seeds 5 and 7 (narrow 0.073 -> 0.172 hollow there); on seeds 1 and 4 the narrow fit is
    // kept either way and hollows 0.72 -> 0.81 and 0.51 -> 0.58 of those nodes (a ball that
    // takes the tip of a thin part leaves much of its inside outside any fit)
    let truth = common::load_mesh(Path::new(common::COW));
    let (pts, centre, r) = with_hole_centre(&truth, CAP_COW.0, CAP_COW.1);
    let f = first_fit(&pts, UNIFORM_DEALT);
    let support = DataSupport::new(&f.data.centres, choice::FACTOR);
    let wide = f.search.blobs(&f.lattice, CLEARANCE);
    let narrow = f.search.blobs(&f.lattice, choice::NARROW * support.spacing);
    let fit = |blobs: &Blobs| {
        let spline = solve_serial(&second_system(&f.prep, &f.data, blobs), &f.k, SolverKind::Cholesky);
        sample(&Solo, &f.lattice, &f.data.carrier, &spline)
    };
    let (wide_f, narrow_f) = (fit(&wide), fit(&narrow));
    let open = |at: &[[f64; 3]]| vec![0.0; at.len()];
    let winding = |at: &[[f64; 3]]| winding_numbers(&Solo, at, &f.data.centres, &f.normals, f.search.areas());
    let all_surface = |values: &[f64]| unsupported_share(&f.lattice, values, &support, open).0;
    let but_mouths = |values: &[f64]| unsupported_share(&f.lattice, values, &support, winding).0;
    // the lattice nodes inside the true cow within the hole's ball, and the share of them each
    // fit leaves outside its solid
    let norm = &f.data.norm;
    let world = |q: [f64; 3]| -> [f64; 3] { std::array::from_fn(|d| norm.centre[d] + norm.scale * q[d]) };
    let under: Vec<usize> = (0..f.lattice.len())
        .filter(|&i| {
            let q = world(f.lattice.node(i));
            (0..3).map(|d| (q[d] - centre[d]).powi(2)).sum::<f64>() < r * r
                && mesh_winding(&truth, q).abs() > 0.5
        })
        .collect();
    let hollow =
        |values: &[f64]| under.iter().filter(|&&i| values[i] <= 0.0).count() as f64 / under.len() as f64;
    let (all_wide, all_narrow) = (all_surface(&wide_f), all_surface(&narrow_f));
    let (kept_wide, kept_narrow) = (but_mouths(&wide_f), but_mouths(&narrow_f));
    let (hollow_wide, hollow_narrow) = (hollow(&wide_f), hollow(&narrow_f));
    println!(
        "unsupported shares: all surface wide {all_wide:.4} narrow {all_narrow:.4}, but the mouths \
         wide {kept_wide:.4} narrow {kept_narrow:.4}; {} nodes under the hole, outside the solid: \
         wide {hollow_wide:.3}, narrow {hollow_narrow:.3}",
        under.len()
    );
    assert!(all_narrow < all_wide, "without the mouth rule the narrow candidate is not kept");
    assert!(kept_wide < kept_narrow, "with the mouth rule the wide candidate is not kept");
    assert!(under.len() > 200 && hollow_narrow > 1.5 * hollow_wide, "the narrow fit does not hollow the cap");
    // the binary makes the same choice
    let (_, _, line) = fit_mesh("cow-cap", &pts, "32", &[&UNIFORM[..], &NO_TURNS].concat());
    assert!(line.contains("wide kept") && line.contains("fitted three times"), "{line}");
}

/// The vertices of `truth` within 15 % of its bounding box's diagonal of the vertex farthest
/// along `direction` in the box's unit coordinates: the truth under the surface benchmark's
/// hole of that direction ((1, 1, 1) for `open`, (1, 0, 0) for `openx`).
fn under_the_hole(truth: &volspline::mesh::TriMesh, direction: [f64; 3]) -> Vec<[f64; 3]> {
    let all: Vec<f64> = truth.vertices.iter().flatten().copied().collect();
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let radius = 0.15 * volspline::spline::hygiene::diagonal(&lo, &hi);
    let along = |p: &[f64; 3]| (0..3).map(|d| direction[d] * (p[d] - lo[d]) / (hi[d] - lo[d])).sum::<f64>();
    let centre = *truth.vertices.iter().max_by(|a, b| along(a).total_cmp(&along(b))).unwrap();
    let near = |p: &&[f64; 3]| (0..3).map(|d| (p[d] - centre[d]).powi(2)).sum::<f64>() < radius * radius;
    truth.vertices.iter().filter(near).copied().collect()
}

/// The stored samples of the cow with the hole of the surface benchmark's `open` variant (the
/// data within 15 % of the diagonal of the point farthest along (1, 1, 1), the head, left out).
const OPEN_COWS: [&str; 4] =
    ["cow-1000-open", "cow-1000-open-seed2", "cow-1000-open-seed8", "cow-2000-open-seed11"];

#[test]
fn steeper_targets_at_the_rims_lift_the_caps_over_the_open_cows_heads() {
    // the mouth points' targets three times the other off points' slope hold the rim's slope
    // more firmly and the cap follows the surface around the hole further. Truth -> mesh rms
    // over the cow's vertices within the hole's ball, as a fraction of the diagonal (grid 64,
    // the default fit), measured: with the mouth points' targets as the others' 0.0455 / 0.0415
    // / 0.0396 / 0.0386 (mean 0.0413), twice as steep 0.0383 / 0.0332 / 0.0297 / 0.0387 (mean
    // 0.0350), three times (the default) 0.0325 / 0.0278 / 0.0241 / 0.0388 (mean 0.0308; the
    // last cow's fit keeps no mouth point that changes its cap). Measured without the cap
    // points (`--cap-bulge 0`), which hide the slope's effect: pushed by a quarter of their
    // distance from the data (their first rule) 0.0328 / 0.0312 / 0.0322 / 0.0388 (mean 0.0338),
    // by 0.75 of their depth (the default) 0.0220 / 0.0211 / 0.0222 / 0.0388 (mean 0.0280; the
    // first cow 0.0220 with slope 1 as well), the caps then past the truth in places (mesh ->
    // truth, the tests of the mouth points below)
    let (truth, _, diag) = cow_sample(OPEN_COWS[0]);
    let cap = under_the_hole(&truth, [1.0, 1.0, 1.0]);
    assert!(cap.len() > 300, "{} vertices under the hole", cap.len());
    let cap_rms = |name: &str, slope: &[&str]| {
        let (_, pts, _) = cow_sample(name);
        let flags = [&["--orient-side", "try", "--carrier", "auto", "--cap-bulge", "0"][..], slope].concat();
        let (mesh, _, line) = fit_mesh(name, &pts, "64", &flags);
        assert!(line.contains("mouth points: "), "{line}");
        let d = point_mesh_distances(&mesh, &cap);
        let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt() / diag;
        println!("{name} {slope:?}: {line}\n  truth under the hole -> mesh rms {rms:.5}");
        rms
    };
    let rms: Vec<f64> = OPEN_COWS.iter().map(|name| cap_rms(name, &[])).collect();
    let mean = rms.iter().sum::<f64>() / OPEN_COWS.len() as f64;
    assert!(mean < 0.0330, "the caps over the holes: truth -> mesh rms {mean:.5} on average");
    // `--mouth-slope 1` gives the mouth points the other off points' slope: the first cow's
    // cap sags back (0.0455 measured)
    let flat = cap_rms(OPEN_COWS[0], &["--mouth-slope", "1"]);
    assert!(
        flat > rms[0] + 0.004,
        "--mouth-slope 1: truth under the hole -> mesh {flat:.5}, default {:.5}",
        rms[0]
    );
}

/// 1000 area-uniform samples of the bunny with a ball of 15 % of the diagonal around the point
/// farthest along +x left out (seed 3's bunny-1000-openx of the surface benchmark): a hole in
/// the flank, low by the base.
const FLANK_BUNNY: &str = "bunny-1000-openx-seed3";

/// The default fit of the stored sample `name` (grid 64) and the same with `--cap-bulge 0`:
/// for each, truth -> mesh rms over the `truth`'s vertices within the hole's ball around the
/// vertex farthest along `direction` and over all of them, as fractions of the diagonal, and
/// the report's surface line.
fn with_and_without_cap_points(
    truth: &volspline::mesh::TriMesh,
    name: &str,
    direction: [f64; 3],
) -> [(f64, f64, String); 2] {
    let all: Vec<f64> = truth.vertices.iter().flatten().copied().collect();
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);
    let under = under_the_hole(truth, direction);
    assert!(under.len() > 250, "{} vertices under the hole", under.len());
    let pts = read_back(&sample_path(name));
    let fit = |tag: &str, extra: &[&str]| {
        let flags = [&["--orient-side", "try", "--carrier", "auto"][..], extra].concat();
        let (mesh, _, line) = fit_mesh(&format!("{name}-{tag}"), &pts, "64", &flags);
        let d = point_mesh_distances(&mesh, &under);
        let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt() / diag;
        let whole = truth_to_mesh(truth, &mesh, diag);
        println!("{name} {extra:?}: {line}\n  truth under the hole -> mesh {rms:.5}, all of it {whole:.5}");
        (rms, whole, line)
    };
    [fit("pushed", &[]), fit("plain", &["--cap-bulge", "0"])]
}

#[test]
fn cap_points_push_the_cap_over_the_bunnys_flank_toward_the_truth() {
    // tests/data/bunny-1000-openx-seed3.xyz, grid 64, the default fit: the cap over the hole,
    // held at its rim by the mouth points, still sags below the flank, which keeps its bulge
    // across the hole; the cap points (inside points at the cap's crossings, delta 0.75 of
    // their depth below the tangent planes of their rim points) lift it. Truth -> mesh rms over
    // the bunny's vertices within the hole's ball, as a fraction of the diagonal, measured:
    // 0.0276 with `--cap-bulge 0`, 0.0181 with the default (72 cap points; 0.0216 when their
    // delta was a quarter of their distance from the data); over all its vertices 0.0080 ->
    // 0.0061
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let [(pushed, pushed_all, line), (plain, plain_all, plain_line)] =
        with_and_without_cap_points(&truth, FLANK_BUNNY, [1.0, 0.0, 0.0]);
    assert!(line.contains(", 72 cap points"), "{line}");
    assert!(!plain_line.contains("cap point"), "{plain_line}");
    assert!(pushed < 0.0200 && plain > 0.0260, "under the hole: pushed {pushed}, without {plain}");
    assert!(pushed_all < plain_all - 0.0015, "truth -> mesh: pushed {pushed_all}, without {plain_all}");
}

/// 1000 area-uniform samples of the cow with a ball of 15 % of the diagonal around the point
/// farthest along -z left out (seed 1's cow-1000-openmz of the surface benchmark): the rump,
/// the cut end of the body.
const RUMP_COW: &str = "cow-1000-openmz-seed1";

#[test]
fn cap_points_lift_the_cap_over_the_cut_end_of_the_cows_body_most() {
    // tests/data/cow-1000-openmz-seed1.xyz, grid 64: the hole takes the end of the body, whose
    // flanks run along it; the cap's crossings lie deep below the tangent planes of their rim
    // points (most of their distance from the data) and the cap points lift the cap by most of
    // that. Truth -> mesh rms over the cow's vertices within the hole's ball, as a fraction of
    // the diagonal, measured: 0.0381 with `--cap-bulge 0`, 0.0342 with the default (30 cap
    // points); over all its vertices 0.0140 -> 0.0129
    let truth = common::load_mesh(Path::new(common::COW));
    let [(pushed, pushed_all, line), (plain, plain_all, plain_line)] =
        with_and_without_cap_points(&truth, RUMP_COW, [0.0, 0.0, -1.0]);
    assert!(line.contains(", 30 cap points"), "{line}");
    assert!(!plain_line.contains("cap point"), "{plain_line}");
    assert!(pushed < 0.0360 && plain > 0.0370, "under the hole: pushed {pushed}, without {plain}");
    assert!(pushed_all < plain_all - 0.0007, "truth -> mesh: pushed {pushed_all}, without {plain_all}");
}

/// Mesh -> truth rms distance and fraction of vertices beyond 2 % of the truth's diagonal, as
/// fractions of that diagonal.
fn mesh_to_truth(truth: &volspline::mesh::TriMesh, mesh: &volspline::mesh::TriMesh) -> (f64, f64) {
    let all: Vec<f64> = truth.vertices.iter().flatten().copied().collect();
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);
    let d = point_mesh_distances(truth, &mesh.vertices);
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt() / diag;
    let far = d.iter().filter(|&&x| x > 0.02 * diag).count() as f64 / d.len() as f64;
    (rms, far)
}

#[test]
fn the_ray_test_removes_the_false_shell_around_the_cows_legs() {
    // 4000 points of the cow: parts of the legs oriented inward make shells of false solid
    // around them; the ray test finds their points and turns their patches. Measured (grid 64):
    // mesh -> cow rms 0.518 % of the diagonal, 2.40 % of the vertices beyond 2 % without it (the
    // blob step pins part of the shells), 0.238 % and 0.02 % with it (18 patches, 102 points
    // turned). Of seeds 1-14 of the sampler, 10 turn patches; seeds 10 and 14 pass the bounds
    // below, seeds 1-3 come within them on rms (0.84) and not on the far share (0.61-0.65)
    let truth = common::load_mesh(Path::new(common::COW));
    let pts = area_samples(&truth, 4000, 10);
    // the clearance choice and the turns off in both: what is compared is the ray test alone
    let (off, _, off_line) = fit_mesh(
        "cow-rays-off",
        &pts,
        "64",
        &[&UNIFORM[..], &["--orient-rays", "off", "--blob-choice", "off"], &NO_TURNS].concat(),
    );
    let (on, _, on_line) =
        fit_mesh("cow-rays-on", &pts, "64", &[&UNIFORM[..], &["--blob-choice", "off"], &NO_TURNS].concat());
    let ((rms_off, far_off), (rms_on, far_on)) = (mesh_to_truth(&truth, &off), mesh_to_truth(&truth, &on));
    println!("without: {off_line}\n  rms {rms_off:.5}, far {far_off:.4}\nwith: {on_line}\n  rms {rms_on:.5}, far {far_on:.4}");
    assert!(
        !off_line.contains("rays:") && on_line.contains("rays: ") && on_line.contains("fitted twice"),
        "{on_line}"
    );
    assert!(
        rms_on < 0.85 * rms_off && far_on < 0.6 * far_off && far_on < 0.01,
        "mesh -> cow rms {rms_off} -> {rms_on}, far {far_off} -> {far_on}"
    );
}

/// The samples, their true normals, the prepared data, their neighbourhoods and oriented normals.
type CowOriented = (Vec<f64>, Vec<[f64; 3]>, Prepared, Neighbourhoods, Vec<[f64; 3]>);

/// `n` area-uniform samples of the cow with their true normals, prepared for the kernel r with
/// the default carrier, their neighbourhoods and the oriented normals, with the side vote or not.
fn cow_oriented(n: usize, side_vote: bool) -> CowOriented {
    let truth = common::load_mesh(Path::new(common::COW));
    let (pts, normals) = area_samples_with_normals(&truth, n, 7);
    let prep = prepare(&pts, &Kernel::new(3, 2).unwrap(), &Carrier::AutoBall, 1e-6).unwrap();
    assert_eq!(prep.values.len(), n, "no sample may be merged");
    let hoods = neighbourhoods(&prep.centres).unwrap();
    let o = oriented_with(&Solo, &prep.centres, &hoods, side_vote).unwrap();
    (pts, normals, prep, hoods, o.normals)
}

#[test]
fn off_points_go_where_the_oriented_normals_are_trusted_on_the_cow() {
    let (_, truth, prep, hoods, normals) = cow_oriented(1000, true);
    let trust = trusted(&normals, &hoods.knn, hoods.kmax);
    let pick = |want: bool| -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        (0..normals.len()).filter(|&i| trust[i] == want).map(|i| (normals[i], truth[i])).unzip()
    };
    let ((good, good_truth), (bad, bad_truth)) = (pick(true), pick(false));
    let (a, b) = (agreement(&good, &good_truth), agreement(&bad, &bad_truth));
    println!(
        "cow 1000: {} trusted normals, {a:.4} on the true side; {} doubtful, {b:.4}",
        good.len(),
        bad.len()
    );
    // the doubtful normals are where the orientation errs: thin legs, ears, horns (measured:
    // 413 trusted, 98.3 % on the true side; 587 doubtful, 90.8 %)
    assert!(bad.len() > 100 && good.len() > 300, "{} trusted, {} doubtful", good.len(), bad.len());
    assert!(a > 0.97 && b < a - 0.05, "trusted {a}, doubtful {b}");
    let (off, doubt) = default_off_points(&prep, &hoods, &normals);
    // 58.7 % doubtful: below FADE_FROM, so the asked share holds
    assert_eq!((doubt.count, doubt.share), (bad.len(), DOUBTFUL_SHARE));
    // the full rate from trusted points, DOUBTFUL_SHARE of it from the others (less what is dropped)
    let from = |want: bool| off.source.iter().filter(|&&i| trust[i] == want).count() as f64;
    let (want_good, want_bad) = (RATE * good.len() as f64, DOUBTFUL_SHARE * RATE * bad.len() as f64);
    let near = |got: f64, want: f64| near_rate(got, want, off.dropped);
    assert!(near(from(true), want_good), "{} from trusted, {want_good} wanted", from(true));
    assert!(near(from(false), want_bad), "{} from doubtful, {want_bad} wanted", from(false));
}

#[test]
fn where_most_normals_are_doubtful_the_doubtful_points_get_more_of_the_rate() {
    // 1000 of the cow's own vertices, evenly strided through the file as the benchmark's
    // `--sampling strided` takes them: rows of the scan, whose neighbourhoods are lines
    let truth = common::load_mesh(Path::new(common::COW));
    let v = &truth.vertices;
    let n = 1000;
    let pts: Vec<f64> =
        (0..n).flat_map(|i| v[(i as f64 * (v.len() as f64 / n as f64)).floor() as usize]).collect();
    let prep = prepare(&pts, &Kernel::new(3, 2).unwrap(), &Carrier::AutoBall, 1e-6).unwrap();
    let m = prep.values.len();
    let hoods = neighbourhoods(&prep.centres).unwrap();
    let normals = oriented_with(&Solo, &prep.centres, &hoods, true).unwrap().normals;
    let trust = trusted(&normals, &hoods.knn, hoods.kmax);
    let bad = trust.iter().filter(|&&t| !t).count();
    let frac = bad as f64 / m as f64;
    println!("cow's own vertices: {bad} of {m} normals doubtful ({:.1} %)", 100.0 * frac);
    // measured: 870 of 1000 (the 1000 area-uniform samples of the test above: 587)
    assert!(frac > 0.8, "{bad} of {m} doubtful");
    let (off, doubt) = default_off_points(&prep, &hoods, &normals);
    // the share rises linearly from DOUBTFUL_SHARE at 70 % doubtful to 1 at 100 %
    let want = DOUBTFUL_SHARE + (1.0 - DOUBTFUL_SHARE) * (frac - 0.7) / 0.3;
    assert_eq!(doubt.count, bad);
    assert!((doubt.share - want).abs() < 1e-12 && doubt.share > 0.6, "{doubt:?}, {want} wanted");
    let from_bad = off.source.iter().filter(|&&i| !trust[i]).count() as f64;
    let want_bad = doubt.share * RATE * bad as f64;
    assert!(
        near_rate(from_bad, want_bad, off.dropped),
        "{from_bad} off points from doubtful normals, {want_bad} wanted"
    );
}

/// The fit's off points at the default rates (`RATE`, [`DOUBTFUL_SHARE`]) from `normals`.
fn default_off_points(prep: &Prepared, hoods: &Neighbourhoods, normals: &[[f64; 3]]) -> (OffPoints, Doubt) {
    let knn = (&hoods.knn[..], hoods.kmax);
    off_points_by_trust(&prep.centres, normals, &hoods.tree, knn, (RATE, DOUBTFUL_SHARE), Deal::default())
}

/// Whether `got` off points are the `want` a rate asks for: the rate is dealt by striding through
/// the point indices of each kind, so within 5 %, less the `dropped` ones.
fn near_rate(got: f64, want: f64, dropped: usize) -> bool {
    got <= 1.05 * want + 2.0 && got >= 0.95 * want - dropped as f64 - 2.0
}

/// The fraction of `normals` on the side of `truth`.
fn agreement(normals: &[[f64; 3]], truth: &[[f64; 3]]) -> f64 {
    let same =
        normals.iter().zip(truth).filter(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2] > 0.0).count();
    same as f64 / truth.len() as f64
}

/// The bending energy -lambda^T b of the spline of the kernel r through the data of `prep` and
/// the off-point pairs of `normals`, solved directly.
fn pair_energy(prep: &Prepared, hoods: &Neighbourhoods, normals: &[[f64; 3]]) -> f64 {
    let n = normals.len();
    let off = pairs(&prep.centres, normals, &hoods.tree, (ENERGY_LIMIT - n) / 2);
    let (fc, target) = off_value_parts(&off, &prep.points, &prep.carrier, &prep.norm);
    let carrier: Vec<f64> = prep.values.iter().chain(&fc).copied().collect();
    // every point in the one fixed group: H is 1 x 1, the energy of the signs as they are
    patch_energy(&prep.centres, &off, &carrier, &target, &vec![0; n], 0).unwrap()[0]
}

#[test]
fn the_bending_energy_of_turned_patches_is_what_the_patch_matrix_predicts() {
    let (_, truth, prep, hoods, mut normals) = cow_oriented(1000, false);
    let start = normals.clone();
    let before = agreement(&normals, &truth);
    let e = flip_by_energy(&Solo, &prep, &hoods, &mut normals).unwrap();
    let after = agreement(&normals, &truth);
    let (direct_before, direct_after) =
        (pair_energy(&prep, &hoods, &start), pair_energy(&prep, &hoods, &normals));
    println!(
        "cow 1000: agreement {before:.4} -> {after:.4}; {e:?}; energies solved directly {direct_before:.6} -> \
         {direct_after:.6}"
    );
    assert!(e.ran && e.flipped > 0 && !e.turned_all && e.after < e.before, "{e:?}");
    // the energy of the turned signs, predicted from one factorisation and one right-hand side
    // per patch, is that of the spline through the turned pairs solved afresh (the places of
    // a pair are swapped exactly): a wrong sign or a patch's target left out would differ
    for (predicted, direct) in [(e.before, direct_before), (e.after, direct_after)] {
        assert!((predicted - direct).abs() < 1e-8 * direct.abs(), "predicted {predicted}, solved {direct}");
    }
    // measured 0.9330 -> 0.9290 on this sample (0.9200 -> 0.9430 on the surface benchmark's
    // 1000 cow points): the energy does not reliably pick the true signs, see src/surface/energy.rs
    assert!(after > 0.92, "agreement {before} -> {after}");
}

#[test]
fn the_side_vote_turns_inward_patches_of_the_cows_thin_parts() {
    // measured on these samples: 0.9340 -> 0.9615 at 2000 points, 0.9575 -> 0.9647 at 4000
    for (n, bound) in [(2000, 0.95), (4000, 0.961)] {
        let (_, truth, _, _, without) = cow_oriented(n, false);
        let (_, _, _, _, with) = cow_oriented(n, true);
        let (a, b) = (agreement(&without, &truth), agreement(&with, &truth));
        println!("cow {n}: agreement with the true normals {a:.4} without the side vote, {b:.4} with it");
        assert!(a < bound && b > bound, "cow {n}: agreement {a} without the side vote, {b} with it");
    }
}

#[test]
fn side_vote_and_energy_orientation_give_the_same_signs_on_one_two_and_three_ranks() {
    let (pts, _, prep, hoods, mut normals) = cow_oriented(1000, true);
    let e = flip_by_energy(&Solo, &prep, &hoods, &mut normals).unwrap();
    assert!(e.flipped > 0, "{e:?}");
    // the fit's off points (the default rate) from the serially oriented normals
    let (off, _) = default_off_points(&prep, &hoods, &normals);
    let dir = common::temp_dir("orient-ranks");
    let input = dir.join("cow1000.xyz");
    common::write_xyz(&input, &pts);
    for ranks in [1, 2, 3] {
        let p = dir.join(format!("r{ranks}"));
        let p = p.to_str().unwrap();
        let args = [
            "fit",
            input.to_str().unwrap(),
            "--out",
            p,
            "--grid",
            "16",
            "--no-preview",
            "--orient-side",
            "on",
            "--orient-energy",
            "on",
            BALL[0],
            BALL[1],
        ];
        let text = common::run_ok(ranks, &args);
        let line = text.lines().find(|l| l.contains("surface offsurface")).unwrap_or_default();
        assert!(
            line.contains("turned by the side vote") && line.contains("patches turned"),
            "{ranks} ranks: {text}"
        );
        let model = read_model(Path::new(&format!("{p}.model.h5"))).unwrap();
        let n = prep.centres.len();
        assert_eq!(
            &model.spline.centres[n..n + off.centres.len()],
            &off.centres[..],
            "{ranks} ranks: other off-surface points than the serial orientation's"
        );
    }
}

/// `fit DIR/p.xyz --out DIR/s --grid GRID`, the arguments of [`fit_trimmed`]'s fit.
fn fit_args(dir: &Path, grid: &str) -> Vec<String> {
    let (input, prefix) = (dir.join("p.xyz"), dir.join("s"));
    ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", grid, BALL[0], BALL[1]]
        .map(String::from)
        .to_vec()
}

/// Fits `pts` (written to DIR/p.xyz) on 2 ranks with `--trim` and the timings in DIR/s.csv:
/// the folder and the report.
fn fit_trimmed(name: &str, pts: &[f64], grid: &str) -> (common::TempDir, String) {
    let dir = common::temp_dir(name);
    common::write_xyz(&dir.join("p.xyz"), pts);
    let t = dir.join("s.csv");
    let args = fit_args(&dir, grid);
    let args: Vec<&str> =
        args.iter().map(String::as_str).chain(["--trim", "--timings", t.to_str().unwrap()]).collect();
    let text = common::run_ok(2, &args);
    (dir, text)
}

#[test]
fn trimming_leaves_out_the_unsupported_surface_of_the_cow_and_keeps_the_rest() {
    // the cow set of the blob test above: its closed solid keeps bulges and webs no data
    // supports; `--trim` writes beside the closed surface one without the regions of triangles
    // farther than twice the median spacing from every data point that reach twice as far or
    // stand that spacing off the plane of the nearest data. Measured (grid 64, 2 ranks): four
    // regions standing off, 0.83 % of the area, left out; mesh -> cow rms 0.350 -> 0.319 % of the
    // diagonal, vertices beyond 2 % 0.48 -> 0.14 %
    let truth = common::load_mesh(Path::new(common::COW));
    let pts = area_samples(&truth, 1000, 7);
    let (dir, text) = fit_trimmed("cow-trim", &pts, "64");
    let (t, args) = (dir.join("s.csv"), fit_args(&dir, "64"));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let closed = common::load_mesh(&dir.join("s.ply"));
    let trimmed = common::load_mesh(&dir.join("s.trimmed.ply"));
    let removed: f64 = std::fs::read_to_string(&t)
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("trimmed_area_removed,"))
        .unwrap()
        .parse()
        .unwrap();
    let ((rms_closed, far_closed), (rms_trimmed, far_trimmed)) =
        (mesh_to_truth(&truth, &closed), mesh_to_truth(&truth, &trimmed));
    println!(
        "{}\nclosed: rms {rms_closed:.5}, far {far_closed:.4}; trimmed: rms {rms_trimmed:.5}, far {far_trimmed:.4}, \
         {removed:.4} of the area left out",
        text.lines().find(|l| l.contains("trimmed surface")).unwrap_or("")
    );
    assert!(text.contains("trimmed surface (--trim 2:"), "{text}");
    assert!(removed > 0.003 && removed < 0.25, "{removed} of the area left out");
    // the steps of the off-surface method have stages of their own in the table and the timings
    let timings = std::fs::read_to_string(&t).unwrap();
    for stage in ["normals", "orient", "rays", "blobs"] {
        let key = format!("stage_{stage}_max_s,");
        let seconds: f64 =
            timings.lines().find_map(|l| l.strip_prefix(key.as_str())).expect(&key).parse().unwrap();
        assert!(seconds > 0.0, "{stage}: {seconds} s");
        assert!(text.lines().any(|l| l.trim_start().starts_with(stage)), "no {stage} row:\n{text}");
    }
    assert!(
        rms_trimmed < 0.95 * rms_closed && far_trimmed < 0.5 * far_closed,
        "mesh -> cow rms {rms_closed} -> {rms_trimmed}, far {far_closed} -> {far_trimmed}"
    );
    let judged = trim_oracle(&pts, &closed, &trimmed, &text);
    // the region that reaches twice the radius lies within twice the local radius (the cow's
    // sparse samples around it) and goes as one that stands off; the deep rule is exercised on
    // the fully sampled bunny below
    assert!(judged.off > 0 && judged.shallow > 0 && judged.deep == 0, "the test exercises neither rule");
    // eval trims the saved model alike: the model records its data points
    let model = dir.join("s.model.h5");
    let again = dir.join("again");
    let (m, o) = (model.to_str().unwrap(), again.to_str().unwrap());
    common::run_ok(1, &["eval", m, "--out", o, "--grid", "64", "--trim"]);
    assert_eq!(
        common::load_mesh(&dir.join("again.trimmed.ply")),
        trimmed,
        "eval --trim differs from fit --trim"
    );
    // a factor that is not a positive number is refused before any work, and so is an expression
    let bad = common::run(1, &[&args[..], &["--trim", "0"]].concat());
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("not a trimming factor"));
    let expr = format!("offset({m}, 0.1)");
    let bad = common::run(1, &["eval", &expr, "--out", o, "--grid", "16", "--trim"]);
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("not an expression"));
}

#[test]
fn trimming_a_sparsely_scanned_flank_keeps_its_gaps_and_leaves_out_the_bulges() {
    // the cow's own vertices strided to 2000 (its mesh has few vertices on the flanks and many
    // on the head and legs) with Gaussian noise of 0.5 % of the diagonal, denoised by the
    // default: the flank's unsupported surface is one large region lying on the data's surface,
    // with a few triangles off the plane that ten sparse, curved points fit poorly; it stays
    // (too little of it raised), while the bulges beside the legs and head go. Measured (grid
    // 100, 2 ranks): 5 regions left out (1 deep, 4 standing off), 1.75 % of the area; 1 region
    // with a triangle off kept, 18 % of the area, its vertices 0.31 % of the diagonal from the
    // cow (rms), where the trimmed surface's are 0.45 % and the closed one's 0.53 %. Among the
    // noise streams 1-9, 5 spared a region, 0.4-19 % of the area, with the off points dealt by
    // index (the default before)
    let truth = common::load_mesh(Path::new(common::COW));
    let all: Vec<f64> = truth.vertices.iter().flatten().copied().collect();
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let sigma = 0.005 * volspline::spline::hygiene::diagonal(&lo, &hi);
    let stride = truth.vertices.len() as f64 / 2000.0;
    let mut r = Rng(9);
    let pts: Vec<f64> = (0..2000)
        .flat_map(|i| truth.vertices[(i as f64 * stride) as usize])
        .map(|x| x + sigma * r.normal())
        .collect();
    let (dir, text) = fit_trimmed("cow-trim-strided", &pts, "100");
    let t = dir.join("s.csv");
    let figure = |key: &str| -> f64 {
        let timings = std::fs::read_to_string(&t).unwrap();
        timings.lines().find_map(|l| l.strip_prefix(key)?.strip_prefix(',')).unwrap().parse().unwrap()
    };
    let (removed, spared) = (figure("trimmed_area_removed"), figure("trimmed_regions_spared"));
    println!("{}", text.lines().find(|l| l.contains("trimmed surface")).unwrap_or(""));
    assert!(text.contains("points moved onto quadrics"), "the noisy scan is denoised: {text}");
    // the data the trimming measures against are the denoised points the model records
    let model = read_model(&dir.join("s.model.h5")).unwrap();
    let data = model.data_points().unwrap();
    assert_eq!(data.len(), pts.len());
    let closed = common::load_mesh(&dir.join("s.ply"));
    let trimmed = common::load_mesh(&dir.join("s.trimmed.ply"));
    let judged = trim_oracle(&data, &closed, &trimmed, &text);
    assert_eq!(judged.declined as f64, spared);
    assert!(judged.declined > 0 && judged.off > 0, "the test exercises neither rule");
    assert!(removed < 0.05, "{removed} of the area left out");
    // what stays with the region spared lies on the cow, what goes stands off it
    let (rms_closed, _) = mesh_to_truth(&truth, &closed);
    let (rms_trimmed, _) = mesh_to_truth(&truth, &trimmed);
    let used: std::collections::BTreeSet<u32> = judged.spared.triangles.iter().flatten().copied().collect();
    let spared = volspline::mesh::TriMesh {
        vertices: used.iter().map(|&v| judged.spared.vertices[v as usize]).collect(),
        triangles: Vec::new(),
    };
    let (rms_spared, _) = mesh_to_truth(&truth, &spared);
    let spared_area = volspline::mesh::trim::area(&judged.spared) / volspline::mesh::trim::area(&closed);
    println!(
        "mesh -> cow rms {rms_closed:.5} closed, {rms_trimmed:.5} trimmed, {rms_spared:.5} in the regions \
         spared ({spared_area:.4} of the area)"
    );
    assert!(rms_trimmed < rms_closed, "mesh -> cow rms {rms_closed} -> {rms_trimmed}");
    assert!(
        spared_area > 0.1 && rms_spared < rms_trimmed,
        "{spared_area} of the area spared at {rms_spared}"
    );
}

/// What [`trim_oracle`] found: the regions left out (deep, standing off), those with a triangle
/// off that stay (too little of their area raised), the unsupported triangles kept, and the
/// triangles of the regions that stay with a triangle off (with all the closed surface's
/// vertices).
struct TrimJudged {
    deep: usize,
    off: usize,
    declined: usize,
    shallow: usize,
    spared: volspline::mesh::TriMesh,
}

/// Checks that `trimmed` is `closed` without exactly the unsupported regions that reach deep or
/// stand off the data points `pts`, and that `text` (the fit's report) counts them so.
fn trim_oracle(
    pts: &[f64],
    closed: &volspline::mesh::TriMesh,
    trimmed: &volspline::mesh::TriMesh,
    text: &str,
) -> TrimJudged {
    // exactly the unsupported regions that reach deep or stand off the data are left out: each
    // triangle of the closed surface judged against all the data points by brute force (the
    // plane of its 10 nearest through their mean and the smallest eigenvector of their scatter),
    // with the radius from the median spacing computed here, its region made of the unsupported
    // triangles joined through shared vertices
    let data: Vec<[f64; 3]> = pts.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
    let d2 = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>();
    let nearest: Vec<f64> = data
        .iter()
        .enumerate()
        .map(|(i, p)| {
            data.iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, q)| d2(p, q))
                .fold(f64::INFINITY, f64::min)
        })
        .map(f64::sqrt)
        .collect();
    let upper_median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let radius = 2.0 * upper_median(nearest.clone());
    // the 10 data points nearest to c, nearest first
    let nearest_ten = |c: &[f64; 3]| {
        let mut by_distance: Vec<usize> = (0..data.len()).collect();
        by_distance.sort_by(|&a, &b| d2(&data[a], c).total_cmp(&d2(&data[b], c)));
        by_distance.truncate(10);
        by_distance
    };
    // twice the radius, or twice the local radius (2 times the median spacing of those ten)
    // where the data there are sparser
    let deep = |c: &[f64; 3]| {
        let local = 2.0 * upper_median(nearest_ten(c).iter().map(|&i| nearest[i]).collect());
        2.0 * radius.max(local)
    };
    let off_plane = |c: &[f64; 3]| {
        let q: Vec<&[f64; 3]> = nearest_ten(c).iter().map(|&i| &data[i]).collect();
        let mean: [f64; 3] = std::array::from_fn(|d| q.iter().map(|p| p[d]).sum::<f64>() / 10.0);
        let scatter: [[f64; 3]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|s| q.iter().map(|p| (p[r] - mean[r]) * (p[s] - mean[s])).sum::<f64>())
        });
        let (_, v) = volspline::surface::normals::symmetric_eigen3(scatter);
        (0..3).map(|d| v[d][0] * (c[d] - mean[d])).sum::<f64>().abs()
    };
    // per triangle: 0 supported, 1 unsupported, 2 unsupported and off the data's plane by more
    // than the radius, 3 unsupported beyond twice the radius (or the local radius), 4
    // unsupported and off the plane by more than half the radius (raised)
    let class: Vec<u8> = closed
        .triangles
        .iter()
        .map(|t| {
            let c = volspline::mesh::trim::centroid(closed, t);
            let d = data.iter().map(|p| d2(p, &c)).fold(f64::INFINITY, f64::min).sqrt();
            match d {
                d if d <= radius => 0,
                d if d > deep(&c) => 3,
                _ => match off_plane(&c) {
                    o if o > radius => 2,
                    o if o > 0.5 * radius => 4,
                    _ => 1,
                },
            }
        })
        .collect();
    let mut region: Vec<usize> = (0..closed.vertices.len()).collect();
    fn root(region: &mut [usize], v: usize) -> usize {
        if region[v] == v {
            v
        } else {
            let r = root(region, region[v]);
            region[v] = r;
            r
        }
    }
    for (t, c) in closed.triangles.iter().zip(&class) {
        if *c > 0 {
            for v in &t[1..] {
                let (a, b) = (root(&mut region, t[0] as usize), root(&mut region, *v as usize));
                region[b] = a;
            }
        }
    }
    let (mut deep, mut off) = (std::collections::HashSet::new(), std::collections::HashSet::new());
    // per region: its area and the area raised or off the plane
    let mut areas = std::collections::HashMap::<usize, [f64; 2]>::new();
    let mut declined = std::collections::HashSet::new();
    for (t, c) in closed.triangles.iter().zip(&class) {
        let r = root(&mut region, t[0] as usize);
        match c {
            3 => deep.insert(r),
            2 => off.insert(r),
            _ => false,
        };
        if *c > 0 {
            let area = volspline::mesh::trim::triangle_area(closed, t);
            let e = areas.entry(r).or_default();
            e[0] += area;
            e[1] += if *c == 2 || *c == 4 { area } else { 0.0 };
        }
    }
    // a region with a triangle off goes when at least the raised share of its area is raised
    let off: std::collections::HashSet<usize> = off
        .difference(&deep)
        .copied()
        .filter(|r| {
            let [all, raised] = areas[r];
            let goes = raised >= volspline::mesh::trim::RAISED_SHARE * all;
            if !goes {
                declined.insert(*r);
            }
            goes
        })
        .collect();
    // the triangles of the regions spared
    let spared = volspline::mesh::TriMesh {
        vertices: closed.vertices.clone(),
        triangles: closed
            .triangles
            .iter()
            .filter(|t| declined.contains(&root(&mut region, t[0] as usize)))
            .copied()
            .collect(),
    };
    let declined = declined.len();
    let key = |m: &volspline::mesh::TriMesh, t: &[u32; 3]| {
        volspline::mesh::trim::centroid(m, t).map(|x| (x * 1e9).round() as i64)
    };
    let kept: std::collections::HashSet<[i64; 3]> =
        trimmed.triangles.iter().map(|t| key(trimmed, t)).collect();
    let mut shallow = 0;
    for (t, c) in closed.triangles.iter().zip(&class) {
        let r = root(&mut region, t[0] as usize);
        let goes = *c > 0 && (deep.contains(&r) || off.contains(&r));
        shallow += usize::from((*c == 1 || *c == 4) && !goes);
        let at = volspline::mesh::trim::centroid(closed, t);
        assert_eq!(kept.contains(&key(closed, t)), !goes, "triangle at {at:?}, class {c}");
    }
    println!(
        "{} deep regions and {} standing off left out, {shallow} unsupported triangles kept in shallow regions, \
         {declined} regions with a triangle off kept (too little of them raised)",
        deep.len(),
        off.len()
    );
    let regions = format!(
        "{} regions ({} reaching deep, {} standing off; {declined} standing off with less of their area raised kept)",
        deep.len() + off.len(),
        deep.len(),
        off.len()
    );
    assert!(text.contains(&regions), "{regions}: {text}");
    TrimJudged { deep: deep.len(), off: off.len(), declined, shallow, spared }
}

/// The boundary loops of `mesh`: closed chains of the edges that only one triangle uses.
fn boundary_loops(mesh: &volspline::mesh::TriMesh) -> usize {
    let mut uses = std::collections::HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
            *uses.entry((a, b)).or_insert(0) += 1;
        }
    }
    let mut joined: Vec<usize> = (0..mesh.vertices.len()).collect();
    fn root(joined: &mut [usize], mut v: usize) -> usize {
        while joined[v] != v {
            joined[v] = joined[joined[v]];
            v = joined[v];
        }
        v
    }
    let mut on_boundary = std::collections::HashSet::new();
    for (&(a, b), _) in uses.iter().filter(|(_, n)| **n == 1) {
        let (ra, rb) = (root(&mut joined, a as usize), root(&mut joined, b as usize));
        joined[rb] = ra;
        on_boundary.extend([a as usize, b as usize]);
    }
    on_boundary.iter().map(|&v| root(&mut joined, v)).collect::<std::collections::HashSet<_>>().len()
}

#[test]
fn trimming_a_fully_sampled_scan_opens_only_the_holes_of_the_scan() {
    // 20,000 area-uniform samples of the bunny, whose mesh has five holes in its base: random
    // sampling leaves about 6 % of a surface farther than twice the median spacing from every
    // sample, which a single threshold cut out as 1018 small holes over 7.3 % of the area
    // (grid 100, 2 ranks); only regions that reach twice as far go, the caps over the base's
    // holes: 6 loops, 1.6 % of the area
    let truth = common::load_mesh(Path::new(common::BUNNY));
    assert_eq!(boundary_loops(&truth), 5, "the bunny's own holes");
    let pts = area_samples(&truth, 20_000, 1);
    let dir = common::temp_dir("bunny-trim-full");
    let input = dir.join("p.xyz");
    common::write_xyz(&input, &pts);
    let prefix = dir.join("s");
    let text = common::run_ok(
        2,
        &["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "100", "--trim"],
    );
    let line = text.lines().find(|l| l.contains("trimmed surface")).expect("a trimmed surface line");
    let trimmed = common::load_mesh(&dir.join("s.trimmed.ply"));
    let loops = boundary_loops(&trimmed);
    let left_out = 1.0
        - volspline::mesh::trim::area(&trimmed)
            / volspline::mesh::trim::area(&common::load_mesh(&dir.join("s.ply")));
    println!("{line}\n{loops} boundary loops, {:.2} % of the area left out", 100.0 * left_out);
    assert!((5..=10).contains(&loops), "{loops} holes in the trimmed bunny");
    assert!(left_out > 0.002 && left_out < 0.03, "{left_out} of the area left out");
    // every hole of the bunny is opened: each of its boundary loops lies near a loop of the
    // trimmed surface (within the 4 % of the diagonal that a cap's cut takes at most)
    let diag = {
        let (lo, hi) = truth.vertices.iter().fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), v| {
            ([0, 1, 2].map(|d| lo[d].min(v[d])), [0, 1, 2].map(|d| hi[d].max(v[d])))
        });
        (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt()
    };
    let rim = |m: &volspline::mesh::TriMesh| -> Vec<[f64; 3]> {
        let mut uses = std::collections::HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                *uses.entry((t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))).or_insert(0) += 1;
            }
        }
        uses.iter().filter(|(_, n)| **n == 1).map(|(&(a, _), _)| m.vertices[a as usize]).collect()
    };
    let (holes, cuts) = (rim(&truth), rim(&trimmed));
    let far = holes
        .iter()
        .map(|h| {
            cuts.iter().map(|c| (0..3).map(|d| (h[d] - c[d]).powi(2)).sum::<f64>()).fold(f64::MAX, f64::min)
        })
        .fold(0.0, f64::max)
        .sqrt();
    assert!(far < 0.04 * diag, "a hole of the bunny {far} from every cut");
}

#[test]
fn turning_the_patch_under_unsupported_surface_removes_the_bulge_on_the_bunny() {
    // 1000 area-uniform samples of the bunny (seed 2 of the tests' sampler): with
    // --orient-turns on, one patch of 28 points is turned and the unsupported lattice crossings
    // fall 857 -> 726. Measured (grid 64, 2 ranks): mesh -> bunny rms 0.504 -> 0.338 % of the
    // diagonal, vertices beyond 2 % 1.46 -> 0.19 %. On seeds 1-6 of the bunny and the cow at
    // 1000 points the turns changed 5 of 12 fits, each for the better
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let pts = area_samples(&truth, 1000, 2);
    let (off, _, off_line) = fit_mesh("bunny-turns-off", &pts, "64", &["--orient-turns", "off"]);
    let (on, _, on_line) = fit_mesh("bunny-turns-on", &pts, "64", &["--orient-turns", "on"]);
    let ((rms_off, far_off), (rms_on, far_on)) = (mesh_to_truth(&truth, &off), mesh_to_truth(&truth, &on));
    println!(
        "without: rms {rms_off:.5}, far {far_off:.4}\nwith: {on_line}\n  rms {rms_on:.5}, far {far_on:.4}"
    );
    assert!(!off_line.contains("turns:"), "{off_line}");
    let turns = on_line.split("turns: ").nth(1).expect("the report has the turns").split(';').next().unwrap();
    let turned: usize = turns.split(' ').next().unwrap().parse().unwrap();
    assert!(turned >= 1, "{turns}");
    assert!(
        rms_on < 0.8 * rms_off && far_on < 0.4 * far_off,
        "rms {rms_off} -> {rms_on}, far {far_off} -> {far_on}"
    );
}

/// Bunny samples at which the system is below the projected Cholesky's size (no factor kept)
/// and the turns turn patches, dealt among neighbours (measured: see the tests below; seed 5
/// turned one dealt by index).
const SMALL_TURNS_BUNNY: (usize, u64) = (400, 6);

#[test]
fn the_turns_of_a_small_system_refit_afresh_alike_on_one_two_and_three_ranks() {
    // about 560 rows, solved by Householder QR: no factor is kept, so each try is a fresh fit
    let (dir, input) = sampled_input(
        "small-turns-oracle",
        "bunny.xyz",
        common::BUNNY,
        (SMALL_TURNS_BUNNY.0, SMALL_TURNS_BUNNY.1),
    );
    let oracle = serial_offsurface(&read_back(&input), UNIFORM_DEALT, true, true, false);
    let turns = &oracle.turns;
    // measured: 2 of 3 patches (10 points) turned, unsupported crossings 363 -> 269
    assert!(turns.turned > 0 && turns.after < turns.before, "{turns:?}");
    fits_match_the_oracle(&dir, &input, &oracle, "auto", &UNIFORM, &[]);
}

/// Cow samples with a hole (the tests' sampler: points before the hole, seed) on which a turn of
/// step 7 is kept by the open-space rule alone (measured: see the tests below; of the cow at
/// 1000 and 2000 points with a hole and at 1000 without, and the bunny at 1000 with a hole,
/// seeds 1-24, the only one).
const OPEN_SPACE_COW: (usize, u64) = (2000, 16);

/// The clearance choice off (the second fit takes the wide clearance alone).
const NO_CHOICE: [&str; 2] = ["--blob-choice", "off"];

/// The default off-point options, spelt out.
const DEFAULT_RATES: [&str; 4] = ["--off-points", "0.5", "--doubtful-share", "0.4"];

#[test]
fn a_turn_kept_by_open_space_is_the_same_on_one_two_and_three_ranks() {
    let dir = common::temp_dir("open-space-oracle");
    let input = dir.join("cow-open.xyz");
    let cow = common::load_mesh(Path::new(common::COW));
    common::write_xyz(&input, &with_hole(&cow, OPEN_SPACE_COW.0, OPEN_SPACE_COW.1));
    let oracle = serial_offsurface(&read_back(&input), DEFAULT_DEALT, true, true, false);
    let turns = &oracle.turns;
    // measured: two patches of 18 points in all turned, one by the open-space rule, 471 -> 428
    // crossings (with three tries, the open-space turn alone: 471 -> 457)
    assert_eq!((turns.turned, turns.by_open_space, turns.turned_points), (2, 1, 18), "{turns:?}");
    fits_match_the_oracle(&dir, &input, &oracle, "cholesky", &DEFAULT_RATES, &[]);
}

#[test]
fn a_turn_kept_by_open_space_removes_false_solid_beside_the_cow() {
    // the set above with the default options, grid 64: a patch of 9 points is turned although
    // the unsupported crossings fall by 3 % alone (471 -> 457), since those in open space fall by
    // more than 5 %. Measured with three patch tries (no second turn): without the open-space
    // rule (the whole count alone) mesh -> cow rms 0.411 % of the diagonal, 1.10 % of the
    // vertices beyond 2 %; with it 0.392 % and 0.88 %. Six tries turn a second patch of 9 points
    // by the whole count as well
    let truth = common::load_mesh(Path::new(common::COW));
    let pts = with_hole(&truth, OPEN_SPACE_COW.0, OPEN_SPACE_COW.1);
    let (rms, far, line) = fit_to_truth("cow-open-space-turn", &pts, &truth, &[]);
    assert!(line.contains("turned (1 by open space)"), "{line}");
    assert!(rms < 0.0040 && far < 0.0099, "mesh -> cow rms {rms}, far {far}");
}

/// A sample of the cow with a hole (1863 points: seed 11's cow-2000-open of the surface
/// benchmark) on which a group of points facing a sheet is turned. The group stands on the
/// underside of the left ear, a sheet thinner than the sampling, one side of it turned; no
/// patch of the ear is small enough to try. (With six patch tries, none of 240 samples of the
/// tests' own sampler turned a group, 28 of them trying one: the cow at 2000 points with and
/// without a hole, seeds 1-60; at 1000 points without a hole seeds 1-30, with one 31-60; the
/// bunny at 2000 points seeds 1-30, at 1000 31-60.)
const FACING_COW: &str = "cow-2000-open-seed11";

#[test]
fn a_group_facing_a_sheet_is_turned_alike_on_one_two_and_three_ranks() {
    let (dir, input) = (common::temp_dir("facing-oracle"), sample_path(FACING_COW));
    let oracle = serial_offsurface(&read_back(&input), DEFAULT_DEALT, true, true, false);
    let turns = &oracle.turns;
    // measured: one turn, the group of 19 points facing a sheet, by the open-space rule
    assert_eq!((turns.turned, turns.facing_turned, turns.by_open_space), (1, 1, 1), "{turns:?}");
    fits_match_the_oracle(&dir, &input, &oracle, "cholesky", &DEFAULT_RATES, &[]);
}

#[test]
fn turning_a_group_facing_a_sheet_removes_false_solid_beside_the_cow() {
    // the set above with the default options, grid 64: the group of 19 points on the underside
    // of the left ear is turned by the open-space rule, unsupported crossings 708 -> 624; no
    // patch is. Measured: without the groups mesh -> cow rms 0.527 % of the diagonal, 1.76 % of
    // the vertices beyond 2 % (the bulge beside the ear); with the group 0.305 % and 0.18 %
    let (truth, pts, _) = cow_sample(FACING_COW);
    let (rms, far, line) = fit_to_truth("cow-facing-turn", &pts, &truth, &[]);
    assert!(line.contains("1 of the tried groups facing a sheet (1 turned)"), "{line}");
    assert!(rms < 0.0040 && far < 0.008, "mesh -> cow rms {rms}, far {far}");
}

#[test]
fn outside_points_after_the_turns_remove_the_web_between_the_cows_front_legs() {
    // 1000 area-uniform samples of the cow with Gaussian noise of 0.1 % of the diagonal
    // (tests/data/cow-1000-noise0.1-seed3.xyz, seed 3's cow-1000-noise0.1 of the surface
    // benchmark), grid 64: the points of the front legs without off points leave a web of false
    // solid between them that no step before the last removes: 18 outside points for the 140
    // unsupported crossings in open space take all unsupported crossings 313 -> 156. Measured:
    // without them mesh -> cow rms 0.711 % of the diagonal, 3.2 % of the vertices beyond 2 %;
    // with them 0.316 % and 0.31 %. The outside values pull the zero set inward beside the
    // charged points: truth -> mesh 0.669 -> 0.767 %
    let (truth, pts, diag) = cow_sample("cow-1000-noise0.1-seed3");
    let complete = |mesh: &volspline::mesh::TriMesh| truth_to_mesh(&truth, mesh, diag);
    let (off, _, off_line) = fit_mesh("cow-outside-off", &pts, "64", &["--outside-points", "off"]);
    let (on, _, on_line) = fit_mesh("cow-outside-on", &pts, "64", &[]);
    let ((m_off, f_off), (m_on, f_on)) = (mesh_to_truth(&truth, &off), mesh_to_truth(&truth, &on));
    let (t_off, t_on) = (complete(&off), complete(&on));
    println!("without: {off_line}\n  mesh -> truth {m_off:.5} (far {f_off:.5}), truth -> mesh {t_off:.5}");
    println!("with: {on_line}\n  mesh -> truth {m_on:.5} (far {f_on:.5}), truth -> mesh {t_on:.5}");
    assert!(!off_line.contains("outside points"), "{off_line}");
    assert!(on_line.contains("outside points: ") && on_line.contains(": kept"), "{on_line}");
    assert!(on_line.contains("outside points: 18 for 140 crossings in open space"), "{on_line}");
    assert!(m_on < 0.0040 && f_on < 0.01, "with: mesh -> cow rms {m_on}, far {f_on}");
    assert!(m_off > 0.0060 && f_off > 0.02, "without: mesh -> cow rms {m_off}, far {f_off}");
    assert!(t_on < 0.0085, "with: truth -> mesh {t_on} (without {t_off})");
}

#[test]
fn off_points_at_the_mouth_of_a_hole_are_the_same_on_one_two_and_three_ranks() {
    let (dir, input) = (common::temp_dir("mouth-oracle"), sample_path(MOUTH_COW));
    let oracle = serial_offsurface(&read_back(&input), DEFAULT_DEALT, true, true, false);
    // measured: 7 off points at the mouth of the hole, after a patch turned as the smoother
    // spline (a try no count keeps)
    assert_eq!(oracle.mouth, 7);
    // and 8 cap points with them
    assert_eq!(oracle.caps, 8);
    assert_eq!(oracle.turns.smoother, 1, "{:?}", oracle.turns);
    fits_match_the_oracle(&dir, &input, &oracle, "cholesky", &DEFAULT_RATES, &[]);
}

/// 1000 area-uniform samples of the cow with a hole over its head (seed 2's cow-1000-open of
/// the surface benchmark), whose cap sags into the solid without the off points at the mouth.
const MOUTH_COW: &str = "cow-1000-open-seed2";

#[test]
fn off_points_at_the_mouth_of_a_hole_hold_the_cap_over_the_cow() {
    // 1000 area-uniform samples of the cow with a ball of 15 % of the diagonal over its head
    // left out (tests/data/cow-1000-open-seed2.xyz, seed 2's cow-1000-open of the surface
    // benchmark), grid 64: the cap the fit puts over the hole sags into the solid; the points
    // nearest to 3 or more unsupported crossings in the hole's mouth, held on both sides, keep
    // the slope of the surface at the rim and lift the cap: 7 off points (of the rim's points)
    // for 212 crossings in the mouth (after a patch turned as the smoother spline). Measured
    // with their targets three times as steep as the other off points' (the default
    // `--mouth-slope`): truth -> cow (all its vertices) rms 2.26 -> 1.29 % of the diagonal,
    // mesh -> cow 0.495 -> 0.548 % with 1.66 -> 2.04 % of the vertices beyond 2 % (the cap
    // lifted past the truth in places; twice as steep: 1.79 %, 0.477 % and 1.26 %). Measured
    // without the cap points (`--cap-bulge 0`): over this rounded head their push carries the
    // cap further past the truth (with the default: truth -> cow 1.27 %, mesh -> cow 0.986 %
    // with 7.5 % of the vertices beyond 2 %)
    let (truth, pts, diag) = cow_sample(MOUTH_COW);
    let complete = |mesh: &volspline::mesh::TriMesh| truth_to_mesh(&truth, mesh, diag);
    let (off, _, off_line) = fit_mesh("cow-mouth-off", &pts, "64", &["--mouth-points", "off"]);
    let (on, _, on_line) = fit_mesh("cow-mouth-on", &pts, "64", &["--cap-bulge", "0"]);
    let ((m_off, f_off), (m_on, f_on)) = (mesh_to_truth(&truth, &off), mesh_to_truth(&truth, &on));
    let (t_off, t_on) = (complete(&off), complete(&on));
    println!("without: {off_line}\n  mesh -> truth {m_off:.5} (far {f_off:.5}), truth -> mesh {t_off:.5}");
    println!("with: {on_line}\n  mesh -> truth {m_on:.5} (far {f_on:.5}), truth -> mesh {t_on:.5}");
    assert!(!off_line.contains("mouth points"), "{off_line}");
    assert!(on_line.contains("mouth points: 7 for 212 crossings in the mouths of holes"), "{on_line}");
    assert!(t_on < 0.0145 && t_off > 0.021, "truth -> mesh with {t_on}, without {t_off}");
    assert!(m_on < 0.0058 && f_on < 0.022, "with: mesh -> cow rms {m_on}, far {f_on}");
}

/// 1000 area-uniform samples of the cow with a ball of 15 % of the diagonal around the point
/// farthest along +x left out (seed 1's cow-1000-openx of the surface benchmark): a hole in the
/// flank, over the belly.
const FLANK_COW: &str = "cow-1000-openx-seed1";

#[test]
fn the_fitted_carrier_lifts_the_cap_over_a_hole_in_the_flank() {
    // tests/data/cow-1000-openx-seed1.xyz, grid 64, every step of the default: under the ball
    // carrier the cap the fit puts over the hole sags into the body; under the default's
    // carrier, the ellipsoid fitted to the points with the spread of its semi-axes scaled by
    // 0.3 on a log scale (--carrier auto, here 'ellipsoid(0.3)'), the field the spline
    // continues across the hole curves like the body, and the cap follows the flank.
    let (truth, pts, diag) = cow_sample(FLANK_COW);
    let run = |tag: &str, carrier: &str| {
        let (mesh, _, line) = fit_mesh(tag, &pts, "64", &["--orient-side", "try", "--carrier", carrier]);
        let (rms, far) = mesh_to_truth(&truth, &mesh);
        let complete = truth_to_mesh(&truth, &mesh, diag);
        println!("--carrier {carrier}: {line}\n  truth -> mesh {complete:.5}, mesh -> truth {rms:.5} (far {far:.5})");
        (complete, rms, far)
    };
    let (t_ball, m_ball, _) = run("cow-flank-ball", "ball");
    let (t_auto, m_auto, f_auto) = run("cow-flank-ellipsoid", "auto");
    // measured: truth -> mesh (all the cow's vertices) 1.049 -> 0.675 % of the diagonal, mesh ->
    // truth 1.452 -> 0.457 %, vertices beyond 2 % 6.6 -> 0.64 % ('ellipsoid(0.5)': 0.681, 0.516,
    // 1.5 %)
    assert!(t_ball > 0.0095 && m_ball > 0.0120, "ball: truth -> mesh {t_ball}, mesh -> truth {m_ball}");
    assert!(t_auto < 0.0075 && m_auto < 0.0060 && f_auto < 0.02, "auto: {t_auto}, {m_auto}, far {f_auto}");
}

#[test]
fn a_fitted_ellipsoid_carrier_is_resolved_and_reported_with_its_axes() {
    // the carrier the report names: the default's, the fitted ellipsoid with the spread of its
    // semi-axes scaled by 0.3, turned along the cow's principal axes, as 'ellipsoid(0.3)' gives
    // it; the plain carrier method's fitted ball, its default; a spec as given
    let (_, pts, _) = cow_sample(FLANK_COW);
    let dir = common::temp_dir("auto-carrier");
    let input = dir.join("p.xyz");
    common::write_xyz(&input, &pts[..3 * 200]);
    let first = |extra: &[&str]| {
        let prefix = dir.join("s");
        let mut args =
            vec!["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "16"];
        args.extend_from_slice(extra);
        let text = common::run_ok(1, &args);
        let line =
            text.lines().find(|l| l.starts_with("volspline fit:") && l.contains(" carrier ")).unwrap_or("");
        line.rsplit("carrier ").next().unwrap_or("").to_string()
    };
    let auto = first(&["--no-preview"]);
    assert_eq!(auto, first(&["--no-preview", "--carrier", "ellipsoid(0.3)"]));
    let plain = first(&["--no-preview", "--surface", "carrier"]);
    assert_eq!(plain, first(&["--no-preview", "--carrier", "ball"]));
    let given = first(&["--no-preview", "--carrier", "ellipsoid:0,0,0,1,2,3"]);
    let carrier = volspline::spline::Carrier::parse(&auto, 3).unwrap();
    let volspline::spline::Carrier::Ellipsoid { semi_axes, axes: Some(_), .. } = carrier else {
        panic!("auto: {auto}")
    };
    // spread scaled by 0.3: the ratio of the longest to the shortest semi-axis is the fitted
    // ellipsoid's to the power 0.3 (the cow's extents are about 0.87, 0.54 and 0.26 of its
    // half-diagonal: 3.3^0.3 = 1.43, where the halved spread gives 1.83 and a ball 1)
    let ratio =
        semi_axes.iter().fold(0.0f64, |m, &a| m.max(a)) / semi_axes.iter().fold(f64::MAX, |m, &a| m.min(a));
    assert!(ratio > 1.3 && ratio < 1.6, "{semi_axes:?}");
    assert!(plain.starts_with("ball:"), "{plain}");
    assert!(given.starts_with("ellipsoid:0.0,0.0,0.0,1.0,2.0,3.0"), "{given}");
}

/// 2000 area-uniform samples of the bunny with Gaussian noise of 0.5 % of the diagonal on every
/// coordinate (seed 5's bunny-2000-noise0.5 of the surface benchmark), the tip of one ear read
/// as the rim of a hole.
const FOLD_BUNNY: &str = "bunny-2000-noise0.5-seed5";

#[test]
fn the_tip_of_an_ear_is_no_rim_of_a_hole() {
    // tests/data/bunny-2000-noise0.5-seed5.xyz, grid 64: the points at the tip of an ear leave a
    // gap of half a turn among their neighbours, as a hole's rim does, and crossings of winding
    // number about 1/2 lie beyond the tip; but the surface folds back there (a neighbour's
    // normal points against theirs), so they get no off points on both sides, which held the
    // ear open past its tip. Measured: 12 mouth points (19 with the points at folds), mesh ->
    // bunny rms 0.560 -> 0.517 % of the diagonal, 1.62 -> 1.37 % of the vertices beyond 2 %
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let pts = read_back(&sample_path(FOLD_BUNNY));
    let (mesh, _, line) = fit_mesh("bunny-fold", &pts, "64", &[]);
    let (rms, far) = mesh_to_truth(&truth, &mesh);
    println!("{line}\n  mesh -> bunny rms {rms:.5}, far {far:.5}");
    assert!(
        line.contains("mouth points: 12 for") && line.contains("(4 rim points at folds left out)"),
        "{line}"
    );
    assert!(rms < 0.0054 && far < 0.015, "mesh -> bunny rms {rms}, far {far}");
}

#[test]
fn both_side_votes_keep_the_fit_with_less_unsupported_surface_on_one_and_two_ranks() {
    // the set of the test above, grid 64: --orient-side both fits without and with the side
    // vote and keeps the one whose surface crosses fewer lattice cells away from the data
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let pts = read_back(&sample_path(FOLD_BUNNY));
    let (plain, _, _) = fit_mesh("bunny-side-off", &pts, "64", &["--orient-side", "off"]);
    let (side, _, _) = fit_mesh("bunny-side-on", &pts, "64", &["--orient-side", "on"]);
    let dir = common::temp_dir("bunny-side-both");
    let input = dir.join("p.xyz");
    common::write_xyz(&input, &pts);
    let run = |ranks: usize, tag: &str| {
        let (prefix, csv) = (dir.join(tag), dir.join(format!("{tag}.csv")));
        let args = [
            "fit",
            input.to_str().unwrap(),
            "--out",
            prefix.to_str().unwrap(),
            "--grid",
            "64",
            "--orient-side",
            "both",
            "--timings",
            csv.to_str().unwrap(),
            BALL[0],
            BALL[1],
        ];
        let text = common::run_ok(ranks, &args);
        let choice = text.lines().find(|l| l.contains("--orient-side both: unsupported crossings"));
        let timings = std::fs::read_to_string(&csv).unwrap();
        (common::load_mesh(&dir.join(format!("{tag}.ply"))), choice.unwrap_or_default().to_string(), timings)
    };
    let (both, choice_one, timings) = run(1, "one");
    let (two, choice_two, _) = run(2, "two");
    let [(rms_plain, far_plain), (rms_side, far_side), (rms_both, far_both)] =
        [&plain, &side, &both].map(|m| mesh_to_truth(&truth, m));
    println!(
        "{choice_one}\n  mesh -> bunny rms / far: off {rms_plain:.5} / {far_plain:.5}, on {rms_side:.5} / \
         {far_side:.5}, both {rms_both:.5} / {far_both:.5}"
    );
    assert!(choice_one.contains("the fit with the side vote kept"), "{choice_one}");
    assert!(timings.contains("side_choice_kept,with"), "{timings}");
    // the fit kept is the one with the side vote, to the vertex
    assert_eq!(both.vertices.len(), side.vertices.len());
    assert_eq!((rms_both, far_both), (rms_side, far_side));
    assert!(rms_both < 0.9 * rms_plain, "mesh -> bunny rms {rms_plain} -> {rms_both}");
    // two ranks make the same choice from the same counts
    assert_eq!(choice_one, choice_two);
    assert_eq!(two.vertices.len(), both.vertices.len());
    // the two-level compactly supported fit does not make its dense fit twice: refused
    let prefix = dir.join("csrbf");
    let args = ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--method", "csrbf"];
    let out = common::run(1, &[&args[..], &["--surface", "offsurface", "--orient-side", "both"]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--orient-side both makes the dense off-surface fit twice"), "{err}");
    assert!(!prefix.with_extension("ply").exists());
}

/// Seed 14's cow-2000-noise0.1 of the surface benchmark (held out from every choice before the
/// side vote's try): 2000 area-uniform samples of the cow with noise of 0.1 % of the diagonal.
const TAIL_COW: &str = "cow-2000-noise0.1-seed14";

#[test]
fn the_side_vote_tried_as_one_turn_clears_false_solid_beside_the_cows_tail() {
    // grid 64: the default tries the side vote's turns together in step 7 and keeps them (the
    // unsupported crossings fall); without the vote the tail of the cow carries false solid.
    // Measured: the vote turns 24 patches (60 points), unsupported crossings 292 -> 264; mesh ->
    // cow rms 0.367 -> 0.239 % of the diagonal, vertices beyond 2 % 0.77 -> 0.09 %, cow -> mesh
    // 0.515 -> 0.486 %
    let (truth, pts, diag) = cow_sample(TAIL_COW);
    let (off, _, off_line) = fit_mesh("cow-tail-side-off", &pts, "64", &["--orient-side", "off"]);
    let dir = common::temp_dir("cow-tail-side-try");
    let input = dir.join("p.xyz");
    common::write_xyz(&input, &pts);
    let (prefix, csv) = (dir.join("try"), dir.join("try.csv"));
    let args = ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "64"];
    let text = common::run_ok(2, &[&args[..], &BALL, &["--timings", csv.to_str().unwrap()]].concat());
    let timings = std::fs::read_to_string(&csv).unwrap();
    let tried = side_vote_part(&text).expect("the side vote's try in the report");
    println!("{tried}");
    assert!(side_vote_part(&off_line).is_none(), "{off_line}");
    assert_eq!(tried, TAIL_COW_TRY);
    assert!(timings.contains("side_try_kept,true"), "{timings}");
    let one = common::load_mesh(&dir.join("try.ply"));
    let [(rms_off, far_off), (rms_try, far_try)] = [&off, &one].map(|m| mesh_to_truth(&truth, m));
    let (complete_off, complete_try) = (truth_to_mesh(&truth, &off, diag), truth_to_mesh(&truth, &one, diag));
    println!(
        "mesh -> cow rms / far: off {rms_off:.5} / {far_off:.5}, try {rms_try:.5} / {far_try:.5}; \
         cow -> mesh {complete_off:.5} -> {complete_try:.5}"
    );
    assert!(
        rms_try < 0.8 * rms_off && far_try < 0.5 * far_off,
        "mesh -> cow rms {rms_off} -> {rms_try}, far {far_off} -> {far_try}"
    );
    assert!(complete_try < 1.05 * complete_off, "cow -> mesh rms {complete_off} -> {complete_try}");
}

/// The side vote's try on the sample of [`TAIL_COW`] as the report states it.
const TAIL_COW_TRY: &str =
    "side vote: 24 patches (60 points) tried as one turn, unsupported crossings 292 -> 264: kept";

/// The side vote's part of the surface line in a fit's report `text`, if any.
fn side_vote_part(text: &str) -> Option<String> {
    let line = text.lines().find(|l| l.contains("surface offsurface"))?;
    line.split("; ").find(|p| p.starts_with("side vote:")).map(str::to_string)
}

#[test]
fn the_side_vote_tried_as_one_turn_is_the_serial_oracles_on_one_two_and_three_ranks() {
    // the set of the test above with the default options: the serial oracle makes the side
    // vote's try and the turns after it from the library's steps, solving each try afresh with
    // Householder; the binary solves the try and the patches' tries together through the kept
    // Cholesky factor, and must count the same crossings, keep the same turn and end with the
    // same spline on any number of ranks
    let dir = common::temp_dir("cow-tail-side-oracle");
    let input = sample_path(TAIL_COW);
    let oracle = serial_offsurface(&read_back(&input), DEFAULT_DEALT, true, true, true);
    let want = SideTry { patches: 24, points: 60, before: 292, after: 264, kept: true };
    assert_eq!(oracle.turns.side, Some(want));
    for text in fits_match_the_oracle(&dir, &input, &oracle, "cholesky", &DEFAULT_RATES, &[]) {
        assert_eq!(side_vote_part(&text).as_deref(), Some(TAIL_COW_TRY));
    }
}

#[test]
fn turning_a_patch_of_a_small_system_removes_unsupported_surface_on_the_bunny() {
    // the set of the test above with the default rates, grid 64: of five patches tried, two of
    // 10 points in all turned by fresh fits, unsupported crossings 427 -> 293; three groups
    // facing a sheet tried after them, none turned; then 7 outside points (step 8), kept, 293 ->
    // 274. Measured: mesh -> bunny rms 0.917 -> 0.648 % of the diagonal, vertices beyond 2 %
    // 4.49 -> 1.76 %
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let pts = area_samples(&truth, SMALL_TURNS_BUNNY.0, SMALL_TURNS_BUNNY.1);
    let (off, _, off_line) = fit_mesh("bunny-small-turns-off", &pts, "64", &NO_TURNS);
    let (on, _, on_line) = fit_mesh("bunny-small-turns-on", &pts, "64", &[]);
    let ((rms_off, far_off), (rms_on, far_on)) = (mesh_to_truth(&truth, &off), mesh_to_truth(&truth, &on));
    println!("without: {off_line}\n  rms {rms_off:.5}, far {far_off:.4}\nwith: {on_line}\n  rms {rms_on:.5}, far {far_on:.4}");
    let tried =
        "turns: 2 of 8 patches and groups tried (10 points) turned, 3 of the tried groups facing a sheet (0 turned)";
    assert!(!off_line.contains("turns:") && on_line.contains(tried), "{on_line}");
    assert!(
        rms_on < 0.9 * rms_off && far_on < 0.7 * far_off,
        "rms {rms_off} -> {rms_on}, far {far_off} -> {far_on}"
    );
}

#[test]
fn a_patch_whose_turn_smooths_the_spline_is_turned_on_an_open_cow() {
    // 1000 area-uniform samples of the cow with a ball of 15 % of the diagonal over its head
    // left out (tests/data/cow-1000-open-seed8.xyz, seed 8's cow-1000-open of the surface
    // benchmark), grid 64, one rank: the patch tried second removes 20 of the 431 unsupported
    // crossings left after the first turn (4.6 %, under the twentieth a count keeps) and takes
    // 0.22 % of the bending energy off, so it is turned as the smoother spline. Measured with
    // the mouth points' targets twice as steep as the others' (`--mouth-slope 2`; the default 3
    // lifts this cap past the truth, mesh -> cow 0.70-0.72 % with and without the rule):
    // without that rule (the same build with it off) mesh -> cow rms 0.566 % of the diagonal,
    // 2.14 % of the vertices beyond 2 %, truth -> mesh 1.333 %; with it 0.558 %, 1.97 % and
    // 1.291 % (before the steeper mouth points 0.516 %, 1.77 %, 1.66 % without it and 0.475 %,
    // 1.26 %, 1.62 % with it). Measured without the cap points (`--cap-bulge 0`), which push
    // this rounded head's cap past the truth (with the default: 1.097 %, 8.39 % and 1.358 %)
    let (truth, pts, diag) = cow_sample("cow-1000-open-seed8");
    let (mesh, _, line) =
        fit_mesh("cow-smoother-turn", &pts, "64", &["--mouth-slope", "2", "--cap-bulge", "0"]);
    let (rms, far) = mesh_to_truth(&truth, &mesh);
    let complete = truth_to_mesh(&truth, &mesh, diag);
    println!("{line}\n  mesh -> cow rms {rms:.5}, far {far:.5}, truth -> mesh {complete:.5}");
    assert!(line.contains("turns: 2 of 6 patches tried (22 points) turned (1 as smoother)"), "{line}");
    assert!(rms < 0.0060 && far < 0.0205, "mesh -> cow rms {rms}, far {far}");
    assert!(complete < 0.0131, "truth -> mesh {complete}");
}

/// 2000 area-uniform samples of the bunny (seed 3) with Gaussian noise of 0.5 % of the diagonal
/// on every coordinate.
fn noisy_bunny() -> (volspline::mesh::TriMesh, Vec<f64>) {
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let all: Vec<f64> = truth.vertices.iter().flatten().copied().collect();
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let sigma = 0.005 * volspline::spline::hygiene::diagonal(&lo, &hi);
    let mut r = Rng(11);
    let pts = area_samples(&truth, 2000, 3).into_iter().map(|x| x + sigma * r.normal()).collect();
    (truth, pts)
}

#[test]
fn denoising_by_default_brings_a_noisy_bunny_closer_on_one_and_three_ranks_alike() {
    let (truth, pts) = noisy_bunny();
    let (plain, _, _) = fit_mesh("bunny-noisy-plain", &pts, "64", &["--denoise", "off"]);
    let dir = common::temp_dir("bunny-noisy-denoised");
    let input = dir.join("p.xyz");
    common::write_xyz(&input, &pts);
    let run = |ranks: usize, tag: &str| {
        let prefix = dir.join(tag);
        let args = ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "64"];
        let text = common::run_ok(ranks, &args);
        let line = text.lines().find(|l| l.contains("denoise:")).unwrap_or_default().to_string();
        (common::load_mesh(&dir.join(format!("{tag}.ply"))), line)
    };
    let (one, line_one) = run(1, "one");
    let (three, line_three) = run(3, "three");
    let ((rms_plain, far_plain), (rms_one, far_one)) =
        (mesh_to_truth(&truth, &plain), mesh_to_truth(&truth, &one));
    println!("plain: rms {rms_plain:.5} far {far_plain:.4}\ndenoised: rms {rms_one:.5} far {far_one:.4}\n{line_one}");
    // measured: the scale ratio of the misfits 1.15 (noise), 1961 of 2000 points moved (39 with
    // fewer than 8 same-sheet neighbours), noise estimate 0.441 % of the diagonal; mesh -> bunny
    // rms 0.466 -> 0.390 %
    assert!(
        line_one.contains("(noise, below 1.38)") && line_one.contains("of 2000 points moved"),
        "{line_one}"
    );
    assert!(rms_one < 0.9 * rms_plain, "mesh -> bunny rms {rms_plain} -> {rms_one}");
    // every rank projects alike: the same report and the same surface
    assert_eq!(line_one, line_three);
    assert_eq!(one.vertices.len(), three.vertices.len());
    let d = one
        .vertices
        .iter()
        .zip(&three.vertices)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max));
    assert!(d.fold(0.0, f64::max) < 1e-6, "the surfaces on 1 and 3 ranks differ");
}

#[test]
fn denoising_by_default_leaves_a_clean_scan_alone() {
    // measured: the scale ratio of the misfits 2.6 on 1000 clean samples of the bunny
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let dir = common::temp_dir("bunny-clean-auto");
    let input = dir.join("p.xyz");
    common::write_xyz(&input, &area_samples(&truth, 1000, 1));
    let prefix = dir.join("s");
    let text = common::run_ok(
        1,
        &["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "32"],
    );
    let line = text.lines().find(|l| l.contains("denoise:")).unwrap_or_default();
    assert!(line.contains("(curvature, not below 1.38): not applied"), "{text}");
}

#[test]
fn denoise_is_refused_where_it_does_not_apply() {
    let (_, pts) = noisy_bunny();
    let dir = common::temp_dir("bunny-noisy-refused");
    let input = dir.join("p.xyz");
    common::write_xyz(&input, &pts[..3 * 500]);
    let prefix = dir.join("s");
    let args = [
        "fit",
        input.to_str().unwrap(),
        "--out",
        prefix.to_str().unwrap(),
        "--surface",
        "carrier",
        "--denoise",
        "on",
    ];
    let out = common::run(1, &args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--denoise on moves the data of the dense off-surface fit")
            && err.contains("plain carrier"),
        "{err}"
    );
    assert!(!prefix.with_extension("ply").exists());
}

/// `n` points of the closed ellipsoid with semi-axes 1, 0.5 and `c` (thin for small `c`): its two
/// faces area-uniform in their projection on the plane of the long axes, each point on either.
fn thin_ellipsoid(n: usize, c: f64, seed: u64) -> Vec<f64> {
    noisy(n, 0.0, seed, |u, v| {
        let (side, v) = if v < 0.5 { (1.0, 2.0 * v) } else { (-1.0, 2.0 * v - 1.0) };
        let (s, t) = (u.sqrt(), std::f64::consts::TAU * v);
        [s * t.cos(), 0.5 * s * t.sin(), side * c * (1.0 - u).max(0.0).sqrt()]
    })
}

/// Fits the thin ellipsoid of semi-axes 1, 0.5 and `c` at 1000 points (seed 5) on `ranks` ranks
/// with the options `extra`, grid 48: the report, the mesh's vertices and the model.
fn fit_thin_sheet(name: &str, c: f64, ranks: usize, extra: &[&str]) -> (String, Vec<[f64; 3]>, Model) {
    let dir = common::temp_dir(name);
    let input = dir.join("p.xyz");
    common::write_xyz(&input, &thin_ellipsoid(1000, c, 5));
    let prefix = dir.join("s");
    let args =
        ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "48", "--no-preview"];
    let text = common::run_ok(ranks, &[&args[..], &BALL, extra].concat());
    let mesh = common::load_mesh(&dir.join("s.ply"));
    let model = read_model(&dir.join("s.model.h5")).unwrap();
    (text, mesh.vertices, model)
}

/// The vertices farther than `off` from the plane of the thin ellipsoid's long axes.
fn off_the_sheet(vertices: &[[f64; 3]], off: f64) -> usize {
    vertices.iter().filter(|p| p[2].abs() > off).count()
}

#[test]
fn a_sheet_thinner_than_the_sampling_gets_its_normals_by_side_and_stays_a_sheet() {
    // 1000 points on an ellipsoid 0.04 thick, about 0.06 apart: every neighbourhood holds both
    // sides, the orientation turns both sides alike, and the first fit's solid fills the space
    // on one side of the sheet
    let (text, vertices, _) = fit_thin_sheet("thin-sheet-sides", 0.02, 1, &[]);
    assert!(text.contains("solid spilled far beyond the data"), "{text}");
    assert!(text.contains("normals turned by side") && text.contains("nodes: kept"), "{text}");
    assert!(!text.contains("stopped at its limit"), "{text}");
    // the solid made again hugs the sheet: no vertex a quarter of the long side off it, and
    // nearly all within 0.1 (2.5 times its thickness)
    assert_eq!(off_the_sheet(&vertices, 0.25), 0);
    let near = vertices.len() - off_the_sheet(&vertices, 0.1);
    assert!(
        near as f64 >= 0.95 * vertices.len() as f64,
        "{near} of {} vertices near the sheet",
        vertices.len()
    );
    // without the orientation by side, the solid spills past the grid's growth and the warning
    // names the cause
    let (text, vertices, _) = fit_thin_sheet("thin-sheet-spills", 0.02, 1, &["--orient-by-side", "off"]);
    assert!(text.contains("stopped at its limit"), "{text}");
    assert!(text.contains(volspline::app::fit::surface::UNBOUNDED_CAUSE), "{text}");
    assert!(off_the_sheet(&vertices, 0.25) > 0, "the solid reaches far off the sheet");
    // 0.1 thick, the same sampling orients both sides apart and nothing spills
    let (text, vertices, _) = fit_thin_sheet("thin-sheet-thick", 0.05, 1, &[]);
    assert!(!text.contains("solid spilled") && !text.contains("warning"), "{text}");
    assert_eq!(off_the_sheet(&vertices, 0.25), 0);
    // the plain carrier method's warning, where it has one, does not name the orientation
    let (text, _, _) = fit_thin_sheet("thin-sheet-carrier", 0.02, 1, &["--surface", "carrier"]);
    assert!(!text.contains(volspline::app::fit::surface::UNBOUNDED_CAUSE), "{text}");
}

#[test]
fn the_normals_by_side_are_the_same_on_one_two_and_three_ranks() {
    let (text, _, one) = fit_thin_sheet("thin-sheet-r1", 0.02, 1, &[]);
    assert!(text.contains("nodes: kept"), "{text}");
    for ranks in [2, 3] {
        let (text, _, model) = fit_thin_sheet(&format!("thin-sheet-r{ranks}"), 0.02, ranks, &[]);
        assert!(text.contains("nodes: kept"), "{ranks} ranks: {text}");
        assert_eq!(model.spline.centres, one.spline.centres, "{ranks} ranks: other constraint points");
        let dw = common::rel_diff(&model.spline.weights, &one.spline.weights);
        assert!(dw < 1e-9, "{ranks} ranks: weights differ by {dw:e}");
    }
}
