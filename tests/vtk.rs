//! The VTKHDF volume written by 2 ranks is read back by VTK's own reader (the `vtk` Python wheel,
//! installed by jobs/setup.sh): dimensions, origin, spacing and every value must be what volspline
//! computed, in VTK's point order; the curvature arrays of `--curvature` are read beside it.

mod common;

use std::process::Command;

use volspline::io::model_file::read_model;

#[test]
fn vtk_reads_the_volume_as_written() {
    let dir = common::temp_dir("vtk");
    let input = dir.join("bunny.xyz");
    common::write_xyz(&input, &common::bunny_subset(25, 0));
    let prefix = dir.join("b");
    common::run_ok(
        2,
        &[
            "fit",
            input.to_str().unwrap(),
            "--out",
            prefix.to_str().unwrap(),
            "--grid",
            "17,13,11",
            "--curvature",
        ],
    );
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/py/vtk_read.py");
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(&python)
        .arg(script)
        .arg(dir.join("b.hdf"))
        .output()
        .expect("python3 is needed for this test (run jobs/setup.sh)");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "VTK could not read the file (run jobs/setup.sh to install vtk):\n{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = |key: &str| -> Vec<String> {
        text.lines()
            .find_map(|l| l.strip_prefix(&format!("{key} ")))
            .unwrap_or_else(|| panic!("no '{key}' in VTK output:\n{text}"))
            .split(' ')
            .map(String::from)
            .collect()
    };
    let nums = |key: &str| -> Vec<f64> { line(key).iter().map(|v| v.parse().unwrap()).collect() };
    assert_eq!(line("class"), ["vtkImageData"]);
    assert_eq!(nums("dims"), [17.0, 13.0, 11.0]);
    // the curvature arrays are read beside f, which stays the active scalars
    assert_eq!(line("arrays"), ["f", "gaussian_curvature", "mean_curvature"]);
    assert_eq!(line("scalars"), ["f"]);
    let model = read_model(&dir.join("b.model.h5")).unwrap();
    let (origin, spacing) = (nums("origin"), nums("spacing"));
    // the grid covers the input's box plus the default 5 % margin, in the input's coordinates
    let (lo, hi) = (model.provenance.box_lo, model.provenance.box_hi);
    let longest = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    for d in 0..3 {
        assert!((origin[d] - (lo[d] - 0.05 * longest)).abs() < 1e-9 * longest, "origin {origin:?}");
        let n = [17.0, 13.0, 11.0][d];
        let span = hi[d] - lo[d] + 0.1 * longest;
        assert!((spacing[d] - span / (n - 1.0)).abs() < 1e-9 * longest, "spacing {spacing:?}");
    }
    let f = nums("f");
    assert_eq!(f.len(), 17 * 13 * 11);
    // every value, at VTK's point (i, j, k), is f at that node
    for (pid, v) in f.iter().enumerate() {
        let (i, j, k) = (pid % 17, (pid / 17) % 13, pid / (17 * 13));
        let x = [
            origin[0] + i as f64 * spacing[0],
            origin[1] + j as f64 * spacing[1],
            origin[2] + k as f64 * spacing[2],
        ];
        let expect = model.eval(&x);
        assert!((v - expect).abs() <= 1e-9 * expect.abs().max(1.0), "point {pid}: VTK {v}, model {expect}");
    }
    // both signs occur: the volume contains the surface f = 0
    assert!(f.iter().any(|&v| v > 0.0) && f.iter().any(|&v| v < 0.0));
}
