//! Reading speed of the point readers on large inputs: the same synthetic points as a text list
//! (.xyz), an ascii PLY, a binary little-endian PLY, a binary PCD, a binary STL (a strip of
//! facets through consecutive points, so each point is the corner of three facets and the reader
//! merges them) and an E57 file (one scan of single-precision Cartesian coordinates under a pose,
//! as scanners write them, written by the `e57` crate), and the bunny OBJ shipped with the tests.
//!
//! Usage: `bench_io WORKDIR POINTS REPEAT`. Writes the files into WORKDIR (which must exist),
//! reads each REPEAT times through `volspline::io::points::read_points` and prints one CSV row
//! per read on stdout: `format,points,file_bytes,rep,seconds`. Run by `jobs/bench-io`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use volspline::io::points::read_points;

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny10k.obj");

/// Point `i` of the synthetic cloud: varied magnitudes and digit counts, as real scans have.
fn point(i: usize) -> [f64; 3] {
    [i as f64 * 1e-3, (i % 977) as f64 * 0.125, -(i as f64).sqrt()]
}

/// Writes the three encodings of `n` points into `dir`; returns (format, path) pairs.
fn write_inputs(dir: &Path, n: usize) -> std::io::Result<Vec<(&'static str, PathBuf)>> {
    let mut text = String::with_capacity(n * 40);
    let header = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n\
             property float z\nend_header\n"
        )
    };
    let mut ascii = header("ascii");
    let mut binary = header("binary_little_endian").into_bytes();
    for i in 0..n {
        let p = point(i);
        let _ = writeln!(text, "{} {} {}", p[0], p[1], p[2]);
        let f = p.map(|c| c as f32);
        let _ = writeln!(ascii, "{} {} {}", f[0], f[1], f[2]);
        f.iter().for_each(|c| binary.extend_from_slice(&c.to_le_bytes()));
    }
    let mut stl = vec![b' '; 80];
    stl.extend((n as u32 - 2).to_le_bytes());
    for i in 0..n - 2 {
        stl.extend([0u8; 12]);
        for p in [point(i), point(i + 1), point(i + 2)] {
            p.iter().for_each(|&c| stl.extend_from_slice(&(c as f32).to_le_bytes()));
        }
        stl.extend([0u8; 2]);
    }
    let mut pcd = format!(
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\n\
         VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
    )
    .into_bytes();
    pcd.extend_from_slice(&binary[binary.len() - 12 * n..]);
    let files = [
        ("xyz", "points.xyz", text.into_bytes()),
        ("pcd_binary", "binary.pcd", pcd),
        ("ply_ascii", "ascii.ply", ascii.into_bytes()),
        ("ply_binary", "binary.ply", binary),
        ("stl_binary", "strip.stl", stl),
    ];
    let mut out = Vec::new();
    let e57 = dir.join("scan.e57");
    write_e57(&e57, n).map_err(std::io::Error::other)?;
    out.push(("e57", e57));
    for (format, name, bytes) in files {
        let path = dir.join(name);
        std::fs::write(&path, bytes)?;
        out.push((format, path));
    }
    out.push(("obj_bunny", PathBuf::from(BUNNY)));
    Ok(out)
}

/// The points as one E57 scan of single-precision Cartesian coordinates, posed by a turn about z
/// and a shift.
fn write_e57(path: &Path, n: usize) -> e57::Result<()> {
    use e57::{Quaternion, Record, RecordValue, Transform, Translation};
    let mut file = e57::E57Writer::from_file(path, "bench-file")?;
    let prototype = vec![Record::CARTESIAN_X_F32, Record::CARTESIAN_Y_F32, Record::CARTESIAN_Z_F32];
    let mut scan = file.add_pointcloud("bench-scan", prototype)?;
    let half = 0.3f64;
    scan.set_transform(Some(Transform {
        rotation: Quaternion { w: half.cos(), x: 0.0, y: 0.0, z: half.sin() },
        translation: Translation { x: 10.0, y: -5.0, z: 1.5 },
    }));
    for i in 0..n {
        scan.add_point(point(i).iter().map(|&c| RecordValue::Single(c as f32)).collect())?;
    }
    scan.finalize()?;
    file.finalize()
}

fn run(dir: &Path, n: usize, repeat: usize) -> Result<(), String> {
    let inputs = write_inputs(dir, n).map_err(|e| format!("writing inputs into {}: {e}", dir.display()))?;
    println!("format,points,file_bytes,rep,seconds");
    for (format, path) in &inputs {
        let bytes = std::fs::metadata(path).map_err(|e| format!("{}: {e}", path.display()))?.len();
        for rep in 1..=repeat {
            let start = Instant::now();
            let set = read_points(path).map_err(|e| e.to_string())?;
            let seconds = start.elapsed().as_secs_f64();
            let expected = if *format == "obj_bunny" { 5051 } else { n };
            if set.points.len() != expected {
                return Err(format!("{format}: read {} points, expected {expected}", set.points.len()));
            }
            println!("{format},{},{bytes},{rep},{seconds:.6}", set.points.len());
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let parsed = match args.as_slice() {
        [_, dir, n, repeat] => n.parse::<usize>().ok().zip(repeat.parse::<usize>().ok()).map(|nr| (dir, nr)),
        _ => None,
    };
    let Some((dir, (n, repeat))) = parsed.filter(|(_, (n, r))| *n >= 4 && *r >= 1) else {
        eprintln!("usage: bench_io WORKDIR POINTS REPEAT (POINTS >= 4, REPEAT >= 1)");
        return ExitCode::from(2);
    };
    match run(Path::new(dir), n, repeat) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("bench_io: {e}");
            ExitCode::FAILURE
        }
    }
}
