//! An E57 file written by the reference implementation, libE57Format (through the `pye57` Python
//! package, installed by jobs/setup.sh): bunny points in two scans, each in its own coordinates
//! under its own pose, with points without a return among them. `volspline fit` on 2 ranks must
//! read the points pye57 reads back with the poses applied, and fit them exactly as it fits those
//! points given as an .xyz file: the same point count, the same volume and the same mesh.

mod common;

use std::path::Path;
use std::process::Command;

use volspline::io::model_file::read_model;
use volspline::io::vtkhdf::read_image;

#[test]
fn a_libe57_file_fits_as_its_points_do() {
    let dir = common::temp_dir("e57");
    let world = common::bunny_subset(25, 0);
    let (points, scan, oracle) = (dir.join("world.xyz"), dir.join("scan.e57"), dir.join("oracle.xyz"));
    common::write_xyz(&points, &world);
    // pye57 writes the scans (their coordinates in single precision) and reads them back
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/py/e57_write.py");
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(&python)
        .args([Path::new(script), &points, &scan, &oracle])
        .output()
        .expect("python3 is needed for this test (run jobs/setup.sh)");
    let said = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "pye57 could not write the file (run jobs/setup.sh to install pye57):\n{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let counts: Vec<usize> = said
        .trim()
        .strip_prefix("points ")
        .and_then(|s| s.split_once(" invalid "))
        .map(|(n, k)| vec![n.parse().unwrap(), k.parse().unwrap()])
        .unwrap_or_else(|| panic!("no point counts in '{said}'"));
    let (n, invalid) = (counts[0], counts[1]);
    assert_eq!(n, world.len() / 3);
    assert_eq!(invalid, 3);
    // what pye57 read back is the bunny again, to the single precision the scans were stored in
    let back: Vec<f64> =
        volspline::io::points::read_points(&oracle).unwrap().points.iter().flatten().copied().collect();
    let mut interleaved = vec![0.0; world.len()];
    let first = n.div_ceil(2);
    for (i, p) in back.chunks_exact(3).enumerate() {
        // the first scan holds the even points, the second the odd ones
        let at = if i < first { 2 * i } else { 2 * (i - first) + 1 };
        interleaved[3 * at..3 * at + 3].copy_from_slice(p);
    }
    assert!(common::rel_diff(&interleaved, &world) < 1e-6, "{}", common::rel_diff(&interleaved, &world));

    let fit = |input: &Path, prefix: &str| {
        let prefix = dir.join(prefix);
        let text = common::run_ok(
            2,
            &["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "17,13,11"],
        );
        (text, prefix)
    };
    let (text, from_e57) = fit(&scan, "e57");
    let (_, from_xyz) = fit(&oracle, "xyz");
    // the run says how many scans and points it read, and how many it left out
    let note = format!(
        "E57, 2 scan(s) read, each placed by its pose: {n} points; {invalid} point(s) without a return"
    );
    assert!(text.contains(&note), "no '{note}' in:\n{text}");
    assert!(text.contains(&format!("{n} points read from {}", scan.display())), "{text}");
    // the same volume, node by node, and the same mesh
    let volume = |prefix: &Path| read_image(&prefix.with_extension("hdf"), "f").unwrap();
    let ((grid_e57, f_e57), (grid_xyz, f_xyz)) = (volume(&from_e57), volume(&from_xyz));
    assert_eq!(grid_e57.dims, grid_xyz.dims);
    assert!(
        common::rel_diff(&f_e57, &f_xyz) <= 1e-9,
        "volumes differ by {}",
        common::rel_diff(&f_e57, &f_xyz)
    );
    assert!(f_e57.iter().any(|&v| v > 0.0) && f_e57.iter().any(|&v| v < 0.0), "no surface in the volume");
    let model = read_model(&from_xyz.with_extension("model.h5")).unwrap();
    assert!(common::volume_diff(&from_e57.with_extension("hdf"), &model) <= 1e-9);
    let (mesh_e57, mesh_xyz) = (
        common::load_mesh(&from_e57.with_extension("ply")),
        common::load_mesh(&from_xyz.with_extension("ply")),
    );
    assert!(!mesh_e57.triangles.is_empty());
    assert_eq!(mesh_e57.vertices.len(), mesh_xyz.vertices.len());
    assert_eq!(mesh_e57.triangles, mesh_xyz.triangles);
    let flat = |m: &volspline::mesh::TriMesh| m.vertices.iter().flatten().copied().collect::<Vec<f64>>();
    assert!(common::rel_diff(&flat(&mesh_e57), &flat(&mesh_xyz)) <= 1e-9);
}
