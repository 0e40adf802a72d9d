//! Runs that cannot finish are refused before the heavy work, with the figures and what to do, on
//! every rank count, and leave no output: a dense system larger than the memory (a densely
//! resampled bunny, `--method dense`), a grid larger than the memory, an output prefix that names a directory or a
//! missing one, an absurd thread count.

mod common;

use std::path::Path;

/// `per_face` points on each bunny triangle (barycentric lattice), 3 values per point.
fn resampled_bunny(per_face: usize) -> Vec<f64> {
    let mesh = common::load_mesh(Path::new(common::BUNNY));
    let mut pts = Vec::new();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        for s in 0..per_face {
            let u = ((s * 7919) % 97) as f64 / 97.0;
            let v = ((s * 104_729) % 89) as f64 / 89.0 * (1.0 - u);
            pts.extend((0..3).map(|d| a[d] + u * (b[d] - a[d]) + v * (c[d] - a[d])));
        }
    }
    pts
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_system_too_large_for_memory_is_refused_before_assembly() {
    let dir = common::temp_dir("preflight-dense");
    let input = dir.join("bunny150k.xyz");
    let pts = resampled_bunny(15);
    assert!(pts.len() / 3 > 140_000);
    common::write_xyz(&input, &pts);
    for ranks in [1, 2] {
        let prefix = dir.join(format!("big{ranks}"));
        let args = ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--method", "dense"];
        let out = common::run(ranks, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("not enough memory: the dense system of"), "{err}");
        assert!(err.contains("GB per rank") && err.contains("use --method csrbf"), "{err}");
        assert!(!err.contains("panic"), "{err}");
    }
    assert_eq!(files_in(&dir), ["bunny150k.xyz"]);
}

#[test]
fn a_grid_too_large_and_bad_prefixes_are_refused_with_reasons() {
    let dir = common::temp_dir("preflight-grid");
    let input = dir.join("bunny.xyz");
    common::write_xyz(&input, &common::bunny_subset(25, 0));
    let i = input.to_str().unwrap();
    let p = dir.join("o");
    let missing = dir.join("missing/o");
    let cases: [(&[&str], i32, &str); 4] = [
        (&["fit", i, "--out", p.to_str().unwrap(), "--grid", "4000"], 1, "not enough memory: the grid of"),
        (&["fit", i, "--out", dir.to_str().unwrap()], 2, "expected a file prefix"),
        (&["fit", i, "--out", missing.to_str().unwrap()], 1, "the output directory does not exist"),
        (&["fit", i, "--out", p.to_str().unwrap(), "--threads", "20000"], 2, "at most 1024"),
    ];
    for ranks in [1, 2] {
        for (args, code, message) in &cases {
            let out = common::run(ranks, args);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(*code), "{args:?} on {ranks}: {err}");
            assert!(err.contains(message), "{args:?} on {ranks}: {err}");
        }
    }
    assert_eq!(files_in(&dir), ["bunny.xyz"]);
}
