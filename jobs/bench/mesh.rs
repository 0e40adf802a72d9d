//! Speed of surface extraction: marching cubes over a sphere's implicit function sampled on an
//! N x N x N grid, as one slab, then the weld of the piece into an indexed mesh.
//!
//! Usage: `bench_mesh N REPEAT`. Threads: rayon's default, set by `RAYON_NUM_THREADS`. Prints one
//! CSV row per repetition on stdout:
//! `n,threads,rep,polygonise_s,weld_s,vertices,loop_centres,triangles`, where `loop_centres` counts
//! the vertices added at the centre of loops that could not be triangulated from their crossings.
//! The case tables are built by a first, untimed run. Run by `jobs/bench-mesh`.

use std::process::ExitCode;
use std::time::Instant;

use volspline::mesh::{is_closed_manifold_edges, polygonise, weld, SlabGrid};

/// `r^2 - |p - c|^2` on an n^3 grid over [-1, 1]^3, x fastest.
fn sphere(n: usize, c: [f64; 3], r: f64) -> (Vec<f64>, f64) {
    let h = 2.0 / (n - 1) as f64;
    let mut values = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let d = [i, j, k].map(|m| -1.0 + m as f64 * h);
                let d = [d[0] - c[0], d[1] - c[1], d[2] - c[2]];
                values.push(r * r - (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
            }
        }
    }
    (values, h)
}

fn run(n: usize, repeat: usize) -> Result<(), String> {
    let (values, h) = sphere(n, [0.01, 0.02, 0.03], 0.8);
    let grid = SlabGrid {
        values: &values,
        nx: n,
        ny: n,
        nz: n,
        k0: 0,
        layers: n,
        origin: [-1.0; 3],
        spacing: [h; 3],
    };
    let _ = polygonise(&grid, 0.0);
    let threads = rayon::current_num_threads();
    println!("n,threads,rep,polygonise_s,weld_s,vertices,loop_centres,triangles");
    for rep in 1..=repeat {
        let start = Instant::now();
        let piece = polygonise(&grid, 0.0);
        let polygonise_s = start.elapsed().as_secs_f64();
        let first_centre = 3 * (n * n * n) as u64;
        let centres = piece.edge_ids.iter().filter(|&&id| id >= first_centre).count();
        let start = Instant::now();
        let mesh = weld(&[piece]);
        let weld_s = start.elapsed().as_secs_f64();
        if mesh.triangles.is_empty() || !is_closed_manifold_edges(&mesh) {
            return Err(format!("the {n}^3 sphere is not a closed manifold surface"));
        }
        let (v, t) = (mesh.vertices.len(), mesh.triangles.len());
        println!("{n},{threads},{rep},{polygonise_s:.6},{weld_s:.6},{v},{centres},{t}");
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let parsed = match args.as_slice() {
        [_, n, repeat] => n.parse::<usize>().ok().zip(repeat.parse::<usize>().ok()),
        _ => None,
    };
    let Some((n, repeat)) = parsed.filter(|&(n, r)| n >= 4 && r >= 1) else {
        eprintln!("usage: bench_mesh N REPEAT (N >= 4, REPEAT >= 1)");
        return ExitCode::from(2);
    };
    match run(n, repeat) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("bench_mesh: {e}");
            ExitCode::FAILURE
        }
    }
}
