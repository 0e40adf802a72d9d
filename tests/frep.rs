//! FRep expressions and metamorphosis on reconstructed solids, through the binary and the library:
//! set operations of two bunny fits are the R-functions of their separately evaluated volumes; an
//! offset of a reconstructed sphere moves its surface by the distance; the carrier swap of
//! Figure 5 (a cube from 90 surface points, two spheres moved apart) changes the solid and leaves
//! f at the data points equal to the new carrier minus the old one; malformed expressions fail
//! cleanly; `morph` writes its frames and series; expressions evaluate alike on 1, 2 and 3 ranks.

mod common;

use std::path::{Path, PathBuf};

use common::{load_mesh, run, run_ok, temp_dir, write_xyz};
use volspline::frep::morph::{read_pairs, Morph};
use volspline::frep::{Expr, Implicit};
use volspline::io::vtkhdf::read_image;
use volspline::spline::carrier::{r_intersection, r_union};
use volspline::spline::Carrier;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Fits `pts` (dense, small grid) and returns the model file.
fn fit(dir: &Path, name: &str, pts: &[f64], extra: &[&str]) -> PathBuf {
    let xyz = dir.join(format!("{name}.xyz"));
    write_xyz(&xyz, pts);
    let prefix = dir.join(name);
    let mut args = vec!["fit", s(&xyz), "--out", s(&prefix), "--grid", "8", "--method", "dense"];
    args.extend_from_slice(extra);
    run_ok(0, &args);
    dir.join(format!("{name}.model.h5"))
}

/// `eval EXPR` on `box_` with `n` nodes along the longest side on `ranks`; the volume.
fn eval(ranks: usize, dir: &Path, name: &str, expr: &str, box_: &str, n: usize) -> Vec<f64> {
    let out = dir.join(name);
    run_ok(ranks, &["eval", expr, "--out", s(&out), "--bounds", box_, "--grid", &n.to_string()]);
    read_image(&dir.join(format!("{name}.hdf")), "f").unwrap().1
}

/// Two bunny fits of 400 points each, the second from other vertices and moved by (6, 2, 0).
fn two_bunnies(dir: &Path) -> (PathBuf, PathBuf) {
    let a = fit(dir, "a", &common::bunny_subset(25, 0), &[]);
    let mut moved = common::bunny_subset(25, 11);
    moved.chunks_exact_mut(3).for_each(|p| {
        p[0] += 6.0;
        p[1] += 2.0;
    });
    (a, fit(dir, "b", &moved, &[]))
}

/// An R-function of two operand values.
type RFunction = fn(f64, f64) -> f64;

const BUNNY_BOX: &str = "-11,1,-8,13,21,8";

fn unit(path: &Path) -> f64 {
    Expr::from_text(s(path)).unwrap().unit()
}

#[test]
fn set_operations_of_two_bunnies_are_the_r_functions_of_their_volumes() {
    let dir = temp_dir("frep-setops");
    let (a, b) = two_bunnies(&dir);
    let (ua, ub) = (unit(&a), unit(&b));
    // the unit is |grad f| at the data: the bunny is about 16 across and the default's carrier
    // the fitted ellipsoid, f_c = 1 - sum (x_j / a_j)^2 with semi-axes a_j of some 5-8, so
    // about 2 / a_j (with a ball, r^2 - |x - c|^2, it would be about 2 r, some 16)
    assert!(ua > 0.05 && ua < 2.0 && ub > 0.05 && ub < 2.0, "units {ua} {ub}");
    let fa = eval(0, &dir, "ea", s(&a), BUNNY_BOX, 20);
    let fb = eval(0, &dir, "eb", s(&b), BUNNY_BOX, 20);
    let scale = fa.iter().chain(&fb).map(|v| v.abs() / ua.min(ub)).fold(0.0, f64::max);
    let cases: [(&str, RFunction); 3] =
        [("union", r_union), ("intersection", r_intersection), ("difference", |x, y| r_intersection(x, -y))];
    for (op, rf) in cases {
        let f = eval(2, &dir, op, &format!("{op}({}, {})", s(&a), s(&b)), BUNNY_BOX, 20);
        let worst = f
            .iter()
            .zip(fa.iter().zip(&fb))
            .map(|(v, (x, y))| (v - rf(x / ua, y / ub)).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 1e-12 * scale, "{op}: differs by {worst:e} (scale {scale:e})");
        let inside = f.iter().filter(|v| **v >= 0.0).count();
        assert!(inside > 0, "{op}: empty");
    }
    // the union holds both solids, the intersection lies in both
    let f = eval(0, &dir, "u", &format!("union({},{})", s(&a), s(&b)), BUNNY_BOX, 20);
    let count = |v: &[f64]| v.iter().filter(|x| **x >= 0.0).count();
    assert!(count(&f) > count(&fa).max(count(&fb)), "the union is not larger than either bunny");
}

/// Points on the unit sphere (a Fibonacci spiral).
fn sphere(n: usize) -> Vec<f64> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .flat_map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            [r * phi.cos(), r * phi.sin(), z]
        })
        .collect()
}

#[test]
fn offset_of_a_reconstructed_sphere_moves_its_surface_by_the_distance() {
    let dir = temp_dir("frep-offset");
    let ball = fit(&dir, "sphere", &sphere(300), &[]);
    let bx = "-1.5,-1.5,-1.5,1.5,1.5,1.5";
    let h = 3.0 / 60.0;
    for d in [0.2, -0.3] {
        let out = dir.join("off");
        run_ok(
            0,
            &[
                "eval",
                &format!("offset({}, {d})", s(&ball)),
                "--out",
                s(&out),
                "--bounds",
                bx,
                "--grid",
                "61",
            ],
        );
        let mesh = load_mesh(&dir.join("off.ply"));
        let radii: Vec<f64> =
            mesh.vertices.iter().map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()).collect();
        let mean = radii.iter().sum::<f64>() / radii.len() as f64;
        // the first-order offset of a ball of radius R moves it to d + sqrt(d^2 + R^2)
        let want = d + (d * d + 1.0f64).sqrt();
        let worst = radii.iter().map(|r| (r - want).abs()).fold(0.0, f64::max);
        assert!((mean - want).abs() < 0.02 * h, "d = {d}: mean radius {mean}, want {want}");
        assert!(worst < 0.1 * h, "d = {d}: a vertex {worst} from radius {want}");
        assert!((mean - 1.0 - d).abs() < d * d, "d = {d}: moved by {} instead of {d}", mean - 1.0);
    }
}

/// 90 points on the surface of the cube [-1, 1]^3, from a fixed linear congruential sequence.
fn cube_points() -> Vec<f64> {
    let mut state: u64 = 12345;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..90)
        .flat_map(|_| {
            let face = (next() * 6.0) as usize;
            let mut p = [2.0 * next() - 1.0, 2.0 * next() - 1.0, 2.0 * next() - 1.0];
            p[face / 2] = if face.is_multiple_of(2) { -1.0 } else { 1.0 };
            p
        })
        .collect()
}

const NEAR: &str = "union(ball:-0.6,0,0,1.2,ball:0.6,0,0,1.2)";
const APART: &str = "union(ball:-0.9,0,0,1.2,ball:0.9,0,0,1.2)";

#[test]
fn carrier_swap_of_figure_5_moves_the_solid_and_keeps_the_spline() {
    let dir = temp_dir("frep-swap");
    let pts = cube_points();
    let cube = fit(&dir, "cube", &pts, &["--carrier", NEAR]);
    let swapped = Expr::from_text(&format!("carrier({}, {APART})", s(&cube))).unwrap();
    let (old, new) = (Carrier::parse(NEAR, 3).unwrap(), Carrier::parse(APART, 3).unwrap());
    let mut worst = 0.0f64;
    let mut moved = 0.0f64;
    for p in pts.chunks_exact(3) {
        let x = [p[0], p[1], p[2]];
        let want = new.eval(p) - old.eval(p);
        worst = worst.max((swapped.value(x) - want).abs());
        moved = moved.max(want.abs());
    }
    assert!(moved > 0.3, "the carriers hardly differ at the data ({moved})");
    assert!(worst < 1e-9 * moved, "f at the data differs from the new carrier minus the old by {worst:e}");
    // the deformed solid is longer along x than the cube
    let bx = "-3,-2,-2,3,2,2";
    for (name, expr) in [("cube", s(&cube).to_string()), ("apart", format!("carrier({}, {APART})", s(&cube)))]
    {
        run_ok(2, &["eval", &expr, "--out", s(&dir.join(name)), "--bounds", bx, "--grid", "49"]);
    }
    let width = |name: &str| {
        let m = load_mesh(&dir.join(format!("{name}.ply")));
        let xs = m.vertices.iter().map(|v| v[0]);
        xs.clone().fold(f64::MIN, f64::max) - xs.fold(f64::MAX, f64::min)
    };
    let (w0, w1) = (width("cube"), width("apart"));
    assert!((w0 - 2.0).abs() < 0.3, "the cube is {w0} wide");
    assert!(w1 > w0 + 0.5, "moving the spheres apart did not stretch the solid: {w0} -> {w1}");
}

#[test]
fn malformed_expressions_fail_cleanly_without_output() {
    let dir = temp_dir("frep-bad");
    let a = fit(&dir, "a", &common::bunny_subset(40, 0), &[]);
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let prefix = out.join("e");
    let cases: Vec<(String, i32, String)> = vec![
        (format!("union({},", s(&a)), 2, format!("at {}: expected an operand", s(&a).len() + 8)),
        (format!("offset({}, far)", s(&a)), 2, "expected a number".into()),
        (format!("unoin({0},{0})", s(&a)), 2, "unknown operation 'unoin'".into()),
        (format!("carrier({}, cube)", s(&a)), 2, "unknown carrier".into()),
        (format!("union({}, {})", s(&a), s(&dir.join("missing.model.h5"))), 1, "missing.model.h5".into()),
    ];
    for (expr, code, why) in &cases {
        for ranks in [0, 2] {
            let o = run(ranks, &["eval", expr, "--out", s(&prefix)]);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(*code), "{expr} on {ranks}: {err}");
            assert!(err.contains(why.as_str()), "{expr}: '{why}' not in {err}");
            assert!(std::fs::read_dir(&out).unwrap().next().is_none(), "{expr} left output behind");
        }
    }
    // a bad pairs file of morph
    let pairs = dir.join("pairs.txt");
    std::fs::write(&pairs, "0 0 0 1 1 1\n0 0 1 x 0 0\n").unwrap();
    let o = run(2, &["morph", s(&a), s(&a), "--out", s(&prefix), "--pairs", s(&pairs), "--frames", "2"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("pairs.txt: line 2"), "{err}");
    assert!(std::fs::read_dir(&out).unwrap().next().is_none(), "morph left output behind");
    // two features of the bunny swapping places: their paths meet half-way, where one point
    // would have to show both; refused with the two lines and the place, before any frame
    std::fs::write(
        &pairs,
        "# ear tips swap\n-0.5 1.5 0 0.5 1.5 0\n0 0 0 0 0 0\n0.5 1.5 0 -0.5 1.5 0\n1 0 0 1 0 0\n0 0 1 0 0 1\n",
    )
    .unwrap();
    let o = run(2, &["morph", s(&a), s(&a), "--out", s(&prefix), "--pairs", s(&pairs), "--frames", "3"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("pairs.txt: lines 2 and 4: the two pairs meet on their way at t = 0.5000, (0.000000e0, 1.500000e0, 0.000000e0)"),
        "{err}"
    );
    assert!(std::fs::read_dir(&out).unwrap().next().is_none(), "morph left output behind");
}

#[test]
fn morph_writes_frames_from_a_to_b_and_a_series() {
    let dir = temp_dir("frep-morph");
    let (a, b) = two_bunnies(&dir);
    let (ua, ub) = (unit(&a), unit(&b));
    let fa = eval(0, &dir, "ea", s(&a), BUNNY_BOX, 16);
    let fb = eval(0, &dir, "eb", s(&b), BUNNY_BOX, 16);
    let prefix = dir.join("m");
    let plain = run_ok(
        2,
        &["morph", s(&a), s(&b), "--frames", "3", "--out", s(&prefix), "--bounds", BUNNY_BOX, "--grid", "16"],
    );
    let frame = |k: usize| read_image(&dir.join(format!("m_{k:03}.hdf")), "f").unwrap().1;
    assert_eq!(frame(0), fa);
    assert_eq!(frame(2), fb);
    let mid = frame(1);
    let ut = 0.5 * (ua + ub);
    let scale = fa.iter().map(|v| v.abs()).fold(0.0, f64::max);
    for (m, (x, y)) in mid.iter().zip(fa.iter().zip(&fb)) {
        assert!((m - ut * (0.5 * x / ua + 0.5 * y / ub)).abs() <= 1e-12 * scale);
    }
    for k in 0..3 {
        assert!(dir.join(format!("m_{k:03}.ply")).exists());
    }
    let series = std::fs::read_to_string(dir.join("m.hdf.series")).unwrap();
    assert!(series.contains("\"file-series-version\": \"1.0\""), "{series}");
    for (k, t) in [(0, "0.0"), (1, "0.5"), (2, "1.0")] {
        assert!(series.contains(&format!("{{\"name\": \"m_{k:03}.hdf\", \"time\": {t}}}")), "{series}");
    }

    // controlled: features of A at p_i meet those of B at p'_i half-way
    let pairs = dir.join("pairs.txt");
    std::fs::write(
        &pairs,
        "# x y z x' y' z'\n-9 11 0 -3 13 0\n5 7 4 11 9 4\n-2 17 -3 4 19 -3\n0 5 -5 6 7 -5\n3 12 5 9 14 5\n",
    )
    .unwrap();
    let pp = dir.join("p");
    let controlled = run_ok(
        2,
        &[
            "morph",
            s(&a),
            s(&b),
            "--frames",
            "3",
            "--out",
            s(&pp),
            "--pairs",
            s(&pairs),
            "--bounds",
            BUNNY_BOX,
            "--grid",
            "16",
        ],
    );
    let pframe = |k: usize| read_image(&dir.join(format!("p_{k:03}.hdf")), "f").unwrap().1;
    assert_eq!(pframe(0), fa);
    assert_eq!(pframe(2), fb);
    let (ea, eb) = (Expr::from_text(s(&a)).unwrap(), Expr::from_text(s(&b)).unwrap());
    let list = read_pairs(&pairs).unwrap();
    let half = Morph::new(&ea, &eb, 0.5, Some(&list)).unwrap();
    for (p, q) in &list {
        let mid = [0, 1, 2].map(|d| 0.5 * (p[d] + q[d]));
        let want = ut * (0.5 * ea.value(*p) / ua + 0.5 * eb.value(*q) / ub);
        assert!((half.value(mid) - want).abs() < 1e-9 * ut, "the pair {p:?} -> {q:?} is not met half-way");
    }
    let differ = pframe(1).iter().zip(&mid).filter(|(x, y)| (*x - *y).abs() > 1e-6 * scale).count();
    assert!(differ > mid.len() / 2, "the pairs changed only {differ} of {} nodes", mid.len());
    // the plain blend of two bunnies 6 apart shrinks half-way; led by pairs that follow the shift
    // the half-way bunny keeps its size (its surface about as large as at either end)
    let (tp, tc) = (triangles(&plain), triangles(&controlled));
    println!("morph triangles: plain {tp:?}, led by pairs {tc:?}");
    // measured: plain [636, 344, 608], led by pairs [636, 536, 608] (with one fit per bunny,
    // before the blob search: [700, 368, 688] and [700, 660, 688]; the blob points of the second
    // fit make f steeper beside one bunny than beside the other, and the blend weighs them so)
    assert!(tp[1] < tp[0] * 3 / 4, "plain morph triangles {tp:?}");
    assert!(tc[1] > tc[0] * 4 / 5 && tc[1] > tc[2] * 4 / 5, "controlled morph triangles {tc:?}");
    // pairs that follow the shift fold nothing
    assert!(!controlled.contains("fold"), "{controlled}");

    // two more features, 2 apart on the bunny's back, cross on their way (0.1 apart at t = 0.25):
    // half-way the map into A has to take them back past each other and folds space there
    let crossing = dir.join("crossing.txt");
    let text =
        std::fs::read_to_string(&pairs).unwrap() + "-1 10 0 9 12 0\n# the other one\n1 10 0.2 3 12 -0.2\n";
    std::fs::write(&crossing, text).unwrap();
    // the fold's samples are dealt over the ranks: the same warning, place and determinant on
    // 1, 2 and 3 ranks
    let mut warnings = Vec::new();
    for ranks in [1, 2, 3] {
        let timings = dir.join(format!("fold{ranks}.csv"));
        let args = ["morph", s(&a), s(&b), "--frames", "3", "--out", s(&pp), "--pairs", s(&crossing)];
        let grid = ["--bounds", BUNNY_BOX, "--grid", "16", "--timings", s(&timings)];
        let out = run_ok(ranks, &[&args[..], &grid[..]].concat());
        assert_eq!(out.matches("the space maps fold space").count(), 1, "{out}");
        assert!(out.contains("in 1 of the 3 frames, frame 1 (t = 0.5000)"), "{out}");
        assert!(out.contains("whose map into A folds"), "{out}");
        assert!(out.contains("lines 7 and 9") || out.contains("lines 9 and 7"), "{out}");
        let csv = std::fs::read_to_string(&timings).unwrap();
        assert!(csv.contains("folded_frames,1\n"), "{csv}");
        warnings.push(out.lines().find(|l| l.contains("the space maps fold space")).unwrap().to_string());
    }
    assert!(warnings.iter().all(|w| *w == warnings[0]), "{warnings:#?}");
    // the same features travelling side by side fold nothing
    let apart = dir.join("apart.txt");
    let text = std::fs::read_to_string(&pairs).unwrap() + "-1 10 0 9 12 0\n1 10 0.2 11 12 0.2\n";
    std::fs::write(&apart, text).unwrap();
    let args = ["morph", s(&a), s(&b), "--frames", "3", "--out", s(&pp), "--pairs", s(&apart)];
    let out = run_ok(2, &[&args[..], &["--bounds", BUNNY_BOX, "--grid", "16"][..]].concat());
    assert!(!out.contains("fold"), "{out}");
}

/// The triangles of each frame, from the report of `morph`.
fn triangles(report: &str) -> Vec<usize> {
    let list = report.split("triangles per frame: [").nth(1).and_then(|r| r.split(']').next()).unwrap();
    list.split(',').map(|v| v.trim().parse().unwrap()).collect()
}

#[test]
fn expressions_evaluate_alike_on_one_two_and_three_ranks() {
    let dir = temp_dir("frep-ranks");
    let (a, b) = two_bunnies(&dir);
    let expr = format!(
        "blend_union(offset({}, 0.4), rotate(translate({}, 1,0,0), 0,0,1, 10), 0.5, 1, 1)",
        s(&a),
        s(&b)
    );
    let one = eval(0, &dir, "r1", &expr, BUNNY_BOX, 18);
    for ranks in [2, 3] {
        let more = eval(ranks, &dir, &format!("r{ranks}"), &expr, BUNNY_BOX, 18);
        assert_eq!(one, more, "{ranks} ranks differ from one");
    }
    // the slab evaluation agrees with the pointwise one (rotations and offsets included)
    let e = Expr::from_text(&expr).unwrap();
    let (g, _) = read_image(&dir.join("r1.hdf"), "f").unwrap();
    let scale = one.iter().map(|v| v.abs()).fold(0.0, f64::max);
    for idx in (0..one.len()).step_by(97) {
        let (i, j, k) = (idx % g.dims[0], (idx / g.dims[0]) % g.dims[1], idx / (g.dims[0] * g.dims[1]));
        let v = e.value(g.node(i, j, k));
        assert!((v - one[idx]).abs() < 1e-7 * scale, "node {idx}: {v} != {}", one[idx]);
    }
    assert!(one.iter().any(|v| *v > 0.0) && one.iter().any(|v| *v < 0.0));
}

#[test]
fn contour_models_are_operands_too() {
    let dir = temp_dir("frep-contour");
    let a = fit(&dir, "a", &common::bunny_subset(25, 0), &[]);
    let contours = dir.join("c.txt");
    run_ok(0, &["slice", common::BUNNY, "--out", s(&contours), "--planes", "z:12"]);
    let prefix = dir.join("c");
    run_ok(0, &["contours", s(&contours), "--out", s(&prefix), "--grid", "8"]);
    let c = dir.join("c.model.h5");
    let (ua, uc) = (unit(&a), unit(&c));
    assert!(uc > 0.1 && uc < 1e3 && uc != 1.0, "contour unit {uc}");
    let moved = format!("translate({}, 3,0,0)", s(&c));
    let fa = eval(0, &dir, "ea", s(&a), BUNNY_BOX, 16);
    let fc = eval(0, &dir, "ec", &moved, BUNNY_BOX, 16);
    let expr = format!("intersection({}, {moved})", s(&a));
    let f1 = eval(0, &dir, "i1", &expr, BUNNY_BOX, 16);
    let f2 = eval(2, &dir, "i2", &expr, BUNNY_BOX, 16);
    assert_eq!(f1, f2, "one and two ranks differ");
    // a translated operand is in length units already (unit 1)
    let scale = fa.iter().map(|v| v.abs() / ua).fold(0.0, f64::max);
    for (v, (x, y)) in f1.iter().zip(fa.iter().zip(&fc)) {
        assert!((v - r_intersection(x / ua, *y)).abs() <= 1e-12 * scale);
    }
    assert!(f1.iter().any(|v| *v > 0.0), "the bunny and the moved contour bunny do not overlap");
}

#[test]
fn a_model_whose_name_looks_like_an_expression_is_still_a_model() {
    let dir = temp_dir("frep-oddname");
    let a = fit(&dir, "a", &common::bunny_subset(40, 0), &[]);
    let odd = dir.join("union(x,y).model.h5");
    std::fs::copy(&a, &odd).unwrap();
    let fa = eval(0, &dir, "ea", s(&a), BUNNY_BOX, 12);
    let fo = eval(0, &dir, "eo", s(&odd), BUNNY_BOX, 12);
    assert_eq!(fa, fo);
}

#[test]
fn grids_and_pictures_without_surface_say_why() {
    // a reconstructed sphere (radius 1) on the box [-1.5, 1.5]^3: moved 10 away it is empty there,
    // and its complement covers the whole box; either way no triangle can come, and the run says
    // which, on one rank and on two
    let dir = temp_dir("frep-nothing-to-mesh");
    let ball = fit(&dir, "sphere", &sphere(300), &[]);
    let bx = "-1.5,-1.5,-1.5,1.5,1.5,1.5";
    let cases = [
        (
            "translate({}, 10, 0, 0)",
            Some(
                "f < 0 at all 9261 nodes of the grid: the solid is empty there (or thinner than a cell), so \
                 the surface has no triangles; a finer --grid shows a solid thinner than the cells",
            ),
        ),
        (
            "complement(translate({}, 10, 0, 0))",
            Some("f >= 0 at all 9261 nodes of the grid: the grid lies inside the solid"),
        ),
        ("{}", None),
    ];
    for ranks in [0, 2] {
        for (form, warning) in cases {
            let expr = form.replace("{}", s(&ball));
            let out = dir.join(format!("off{ranks}"));
            let text = run_ok(ranks, &["eval", &expr, "--out", s(&out), "--bounds", bx, "--grid", "21"]);
            let tris: usize = text
                .split("surface f = 0: ")
                .nth(1)
                .and_then(|t| t.split(' ').next())
                .and_then(|t| t.parse().ok())
                .unwrap_or_else(|| panic!("no surface line: {text}"));
            match warning {
                Some(w) => {
                    let ply = dir.join(format!("off{ranks}.ply"));
                    assert!(text.contains(&format!("volspline: warning: {}: {w}", ply.display())), "{text}");
                    assert_eq!(tris, 0, "{text}");
                }
                None => assert!(!text.contains("warning") && tris > 100, "{text}"),
            }
        }
        // the picture of a solid empty in its box: background alone, and said so
        let png = dir.join(format!("empty{ranks}.png"));
        let expr = format!("intersection({0}, translate({0}, 10, 0, 0))", s(&ball));
        let text = run_ok(ranks, &["render", &expr, "--out", s(&png), "--size", "48x32"]);
        assert!(
            text.contains("volspline: warning: no ray met the solid")
                && text.contains("; 0 pixels on the solid"),
            "{text}"
        );
        let png = dir.join(format!("ball{ranks}.png"));
        let text = run_ok(ranks, &["render", s(&ball), "--out", s(&png), "--size", "48x32"]);
        let hits: usize = text.split("; ").nth(1).and_then(|t| t.split(' ').next()).unwrap().parse().unwrap();
        assert!(!text.contains("warning") && hits > 48 * 32 / 10, "{text}");
        // the same ball from too far to fill a pixel, and from inside it: the view is the cause
        for (distance, hits, why) in [
            ("1e30", 0, "spans less than a pixel; leave out --distance to fill the view"),
            ("1e-6", 48 * 32, "is inside the solid, so every ray starts inside"),
        ] {
            let args = ["render", s(&ball), "--out", s(&png), "--size", "48x32", "--distance", distance];
            let text = run_ok(ranks, &args);
            assert!(text.contains(&format!("; {hits} pixels on the solid")), "{text}");
            assert!(text.contains("volspline: warning: ") && text.contains(why), "{text}");
        }
    }
}
