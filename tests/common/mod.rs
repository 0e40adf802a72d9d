//! Shared helpers of the integration tests: real data, temporary folders, running the binary.
#![allow(dead_code)]

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use volspline::io::points::read_points;

pub mod mpijob;

pub const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny10k.obj");
pub const COW: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/cow.obj");
pub const BIN: &str = env!("CARGO_BIN_EXE_volspline");

/// The bunny's vertices, 3 values per point.
pub fn bunny() -> Vec<f64> {
    read_points(Path::new(BUNNY)).unwrap().points.iter().flatten().copied().collect()
}

/// Every `step`-th bunny vertex starting at `offset`.
pub fn bunny_subset(step: usize, offset: usize) -> Vec<f64> {
    bunny().chunks_exact(3).skip(offset).step_by(step).flatten().copied().collect()
}

/// A fresh, empty folder for one test: removed with everything in it when dropped, unless the
/// thread is panicking (a failing test keeps its files for inspection, and says where) or
/// `VOLSPLINE_KEEP_TEST_DIRS` is set.
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl TempDir {
    /// The folder's path, no longer removed on drop (for a folder that outlives this value).
    pub fn into_path(self) -> PathBuf {
        let path = self.0.clone();
        std::mem::forget(self);
        path
    }
}

impl std::ops::Deref for TempDir {
    type Target = PathBuf;
    fn deref(&self) -> &PathBuf {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for TempDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("the test's files are kept in {}", self.0.display());
        } else if std::env::var_os("VOLSPLINE_KEEP_TEST_DIRS").is_none() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A fresh, empty folder for one test (see [`TempDir`]).
pub fn temp_dir(name: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("volspline-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TempDir(d)
}

/// Writes points as an .xyz file with full precision.
pub fn write_xyz(path: &Path, pts: &[f64]) {
    let mut s = String::from("# volspline test points\n");
    for p in pts.chunks_exact(3) {
        s.push_str(&format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]));
    }
    std::fs::write(path, s).unwrap();
}

/// How long one run of the binary may take before it counts as hung: 300 s, or
/// `VOLSPLINE_TEST_TIMEOUT_S`. Generous, for a loaded machine; a hang still fails instead of
/// stalling the suite.
pub fn run_limit() -> Duration {
    let s = std::env::var("VOLSPLINE_TEST_TIMEOUT_S").ok().and_then(|v| v.parse().ok()).unwrap_or(300);
    Duration::from_secs(s)
}

/// What a command printed and how it ended; `timed_out` when it was killed for running past its
/// limit (then `output.status` is the status of the killed process).
pub struct Finished {
    pub output: Output,
    pub timed_out: bool,
}

/// Runs `cmd` with stdout and stderr captured; past `limit` it is sent SIGTERM (mpirun passes it
/// on to its ranks), 10 s later SIGKILL.
pub fn output_within(mut cmd: Command, limit: Duration) -> Finished {
    let mut child =
        cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap_or_else(|e| {
            panic!("failed to start {cmd:?} (is mpirun installed? run jobs/setup.sh): {e}")
        });
    // read both pipes on their own threads, so that a full pipe never blocks the child
    let pipe = |mut r: Box<dyn Read + Send>| {
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            let _ = r.read_to_end(&mut buf);
            let _ = tx.send(buf);
        });
        rx
    };
    let out = pipe(Box::new(child.stdout.take().expect("piped stdout")));
    let err = pipe(Box::new(child.stderr.take().expect("piped stderr")));
    let start = Instant::now();
    let mut timed_out = false;
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for a child process") {
            break status;
        }
        if start.elapsed() > limit && !timed_out {
            timed_out = true;
            let _ = Command::new("kill").args(["-TERM", &child.id().to_string()]).status();
        }
        if start.elapsed() > limit + Duration::from_secs(10) {
            let _ = child.kill();
            break child.wait().expect("waiting for a killed child process");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    // a grandchild that outlived the child may hold a pipe open: do not wait for it for long
    let collect = |rx: mpsc::Receiver<Vec<u8>>| rx.recv_timeout(Duration::from_secs(10)).unwrap_or_default();
    Finished { output: Output { status, stdout: collect(out), stderr: collect(err) }, timed_out }
}

/// Runs the binary under `mpirun -n ranks` (or directly for ranks == 0); panics, with what it
/// printed, when it runs past [`run_limit`].
pub fn run(ranks: usize, args: &[&str]) -> Output {
    let mut cmd = if ranks == 0 {
        Command::new(BIN)
    } else {
        let mut c = Command::new("mpirun");
        c.args(["-n", &ranks.to_string(), "--oversubscribe", BIN]);
        c
    };
    cmd.args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .env("RAYON_NUM_THREADS", "1");
    let limit = run_limit();
    let done = output_within(cmd, limit);
    if done.timed_out {
        panic!(
            "volspline {args:?} on {ranks} ranks did not finish within {} s and was killed (a hang?):\n{}{}",
            limit.as_secs(),
            String::from_utf8_lossy(&done.output.stdout),
            String::from_utf8_lossy(&done.output.stderr)
        );
    }
    done.output
}

/// Runs and asserts success, printing the output on failure.
pub fn run_ok(ranks: usize, args: &[&str]) -> String {
    let out = run(ranks, args);
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "volspline {args:?} on {ranks} ranks failed:\n{text}");
    text
}

/// max |a - b| / max |b|.
pub fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale
}

/// A triangle mesh file (OBJ or PLY) as a `TriMesh`.
pub fn load_mesh(path: &Path) -> volspline::mesh::TriMesh {
    let set = volspline::io::points::read_mesh(path).unwrap();
    volspline::mesh::TriMesh {
        vertices: set.points.clone(),
        triangles: set.triangles.iter().map(|t| [t[0] as u32, t[1] as u32, t[2] as u32]).collect(),
    }
}

/// (mean, 95th percentile, max) of distances divided by `diag`.
pub fn distance_stats(mut d: Vec<f64>, diag: f64) -> (f64, f64, f64) {
    d.iter_mut().for_each(|v| *v /= diag);
    d.sort_by(f64::total_cmp);
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    (mean, d[(d.len() * 95) / 100], d[d.len() - 1])
}

/// The serial reference: the whole bordered system assembled on one process and solved by the
/// dense oracle (Householder for Householder and the projected Cholesky, LU for LU).
pub fn solve_serial(
    prep: &volspline::spline::hygiene::Prepared,
    kernel: &volspline::spline::Kernel,
    solver: volspline::linalg::dist::SolverKind,
) -> volspline::spline::Spline {
    use volspline::linalg::dense::{householder_solve, lu_solve};
    use volspline::linalg::dist::SolverKind;
    let n = volspline::spline::system_size(kernel, prep.values.len());
    let (data, b) = volspline::spline::full_system(kernel, &prep.centres, &prep.values);
    let m = faer::MatRef::from_column_major_slice(&data, n, n);
    let x = match solver {
        SolverKind::Lu => lu_solve(m, &b).unwrap(),
        _ => householder_solve(m, &b).unwrap(),
    };
    volspline::spline::Spline::from_solution(*kernel, prep.centres.clone(), &x, prep.norm)
}

/// This rank's rows (all rows on one process) of the bordered system of `prep`.
pub fn assemble_one(
    prep_centres: &[f64],
    values: &[f64],
    kernel: &volspline::spline::Kernel,
) -> volspline::linalg::dist::LocalRows {
    let n = volspline::spline::system_size(kernel, values.len());
    volspline::app::fit::assemble(
        kernel,
        prep_centres,
        values,
        volspline::linalg::dist::RowCyclic::new(n, 1, 0),
    )
    .expect("the rows fit in memory")
}

/// A small deterministic generator: uniform in [0, 1) and standard normal (Box-Muller).
pub struct Rng(pub u64);

impl Rng {
    pub fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn normal(&mut self) -> f64 {
        let (u, v) = (self.unit().max(1e-300), self.unit());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// `n` points uniform over the area of `mesh`'s triangles (a triangle chosen with probability
/// proportional to its area, then a uniform point in it), from the stream [`Rng`]`(seed)`.
pub fn area_samples(mesh: &volspline::mesh::TriMesh, n: usize, seed: u64) -> Vec<f64> {
    area_samples_with_normals(mesh, n, seed).0
}

/// [`area_samples`] and the unit normal of the triangle each sample lies in (the mesh's
/// orientation: outward for the closed meshes of tests/data).
pub fn area_samples_with_normals(
    mesh: &volspline::mesh::TriMesh,
    n: usize,
    seed: u64,
) -> (Vec<f64>, Vec<[f64; 3]>) {
    let corner = |t: &[u32; 3], k: usize| mesh.vertices[t[k] as usize];
    let area = |t: &[u32; 3]| {
        let (a, b, c) = (corner(t, 0), corner(t, 1), corner(t, 2));
        let (u, v) = ([0, 1, 2].map(|d| b[d] - a[d]), [0, 1, 2].map(|d| c[d] - a[d]));
        let x = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
    };
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in &mesh.triangles {
        total += area(t);
        cumulative.push(total);
    }
    let mut r = Rng(seed);
    let mut normals = Vec::with_capacity(n);
    let points = (0..n)
        .flat_map(|_| {
            let at = r.unit() * total;
            let t = &mesh.triangles[cumulative.partition_point(|&c| c < at).min(mesh.triangles.len() - 1)];
            let (mut s, mut q) = (r.unit(), r.unit());
            if s + q > 1.0 {
                (s, q) = (1.0 - s, 1.0 - q);
            }
            let (a, b, c) = (corner(t, 0), corner(t, 1), corner(t, 2));
            let (u, v) = ([0, 1, 2].map(|d| b[d] - a[d]), [0, 1, 2].map(|d| c[d] - a[d]));
            let x = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            let len = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt().max(f64::MIN_POSITIVE);
            normals.push(x.map(|w| w / len));
            [0, 1, 2].map(|d| a[d] + s * u[d] + q * v[d])
        })
        .collect();
    (points, normals)
}

/// The relative difference ([`rel_diff`]) between the volume `f` of the VTKHDF file `hdf` and
/// `model` evaluated at its grid nodes one by one.
pub fn volume_diff(hdf: &Path, model: &volspline::spline::Model) -> f64 {
    let (grid, values) = volspline::io::vtkhdf::read_image(hdf, "f").unwrap();
    let [nx, ny, nz] = grid.dims;
    let expect: Vec<f64> = (0..nz)
        .flat_map(|kk| (0..ny).flat_map(move |j| (0..nx).map(move |i| (i, j, kk))))
        .map(|(i, j, kk)| model.eval(&grid.node(i, j, kk)))
        .collect();
    rel_diff(&values, &expect)
}

/// A closed contour traced `k` times more finely: k points evenly along each edge, on the
/// straight line between its ends (as a segmentation traced at full resolution gives them).
pub fn traced_finer(c: &[[f64; 2]], k: usize) -> Vec<[f64; 2]> {
    let n = c.len();
    (0..k * n)
        .map(|j| {
            let (i, t) = (j / k, (j % k) as f64 / k as f64);
            let (p, q) = (c[i], c[(i + 1) % n]);
            [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]
        })
        .collect()
}

/// The bunny cut by `planes` (as `slice --planes` takes them), the contour file written into
/// `dir` and read back.
pub fn bunny_slices(dir: &Path, planes: &str) -> Vec<volspline::contour::format::Section> {
    let file = dir.join(format!("bunny-{}.txt", planes.replace(':', "-")));
    run_ok(0, &["slice", BUNNY, "--out", file.to_str().unwrap(), "--planes", planes]);
    volspline::contour::format::read(&file).unwrap()
}
