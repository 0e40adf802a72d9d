//! Orientation agreement with the true normals before and after the energy step
//! (src/surface/energy.rs), for point sets with their true normals beside them.
//!
//!   cargo run --release --example orient_energy -- SET.xyz SET.nrm
//!
//! SET.nrm holds one true outward unit normal per point (x y z per line). Prints how many
//! oriented normals disagree with the truth and why (the estimated normal itself off by more
//! than 60 degrees; in the fixed or the movable patches), the oracle that turns each patch where
//! most of its points are wrong (its energy against the present signs', and the wrong points it
//! would leave), which truly wrong patches a single turn from the present signs would make
//! downhill, and the agreement before and after the step with its figures. With EN_PATCHES set,
//! every patch holding wrong points as (size, wrong, wrong with a good normal).

use std::path::Path;
use std::time::Instant;

use volspline::par::Solo;
use volspline::spline::hygiene::prepare;
use volspline::spline::{Carrier, Kernel};
use volspline::surface::energy::{energy, flip_by_energy, pairs, patch_energy, patches, ENERGY_LIMIT};
use volspline::surface::{neighbourhoods, off_value_parts, oriented_with};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let raw: Vec<f64> = volspline::io::points::read_points(Path::new(&args[1]))
        .unwrap()
        .points
        .iter()
        .flatten()
        .copied()
        .collect();
    let truth: Vec<[f64; 3]> = std::fs::read_to_string(&args[2])
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    let prep = prepare(&raw, &Kernel::new(3, 2).unwrap(), &Carrier::AutoBall, 1e-6).unwrap();
    assert_eq!(prep.values.len(), truth.len(), "points merged: the truth no longer lines up");
    let hoods = neighbourhoods(&prep.centres).unwrap();
    let o = oriented_with(&Solo, &prep.centres, &hoods, false).unwrap();
    let sided = oriented_with(&Solo, &prep.centres, &hoods, true).unwrap();
    let agree = |nn: &[[f64; 3]]| {
        nn.iter().zip(&truth).filter(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2] > 0.0).count() as f64
            / truth.len() as f64
    };
    let before = agree(&o.normals);
    println!(
        "  side vote: agreement {before:.4} -> {:.4}, {:?} patches turned",
        agree(&sided.normals),
        sided.side_turned
    );
    let off = pairs(&prep.centres, &o.normals, &hoods.tree, (ENERGY_LIMIT - truth.len()) / 2);
    let (fc, target) = off_value_parts(&off, &prep.points, &prep.carrier, &prep.norm);
    let mut carrier = prep.values.clone();
    carrier.extend_from_slice(&fc);
    // the oracle: each movable patch turned where most of its points disagree with the truth
    let (patch, m, _) = patches(&prep.centres, &o.normals, &hoods.knn, hoods.kmax, &off);
    let wrong: Vec<bool> =
        o.normals.iter().zip(&truth).map(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2] <= 0.0).collect();
    let mut per = vec![(0usize, 0usize); m + 1];
    for i in 0..wrong.len() {
        per[patch[i]].0 += 1;
        per[patch[i]].1 += usize::from(wrong[i]);
    }
    let mut oracle = vec![1.0; m + 1];
    for p in 0..m {
        if 2 * per[p].1 > per[p].0 {
            oracle[p] = -1.0;
        }
    }
    let h = patch_energy(&prep.centres, &off, &carrier, &target, &patch, m).unwrap();
    let bad = (0..wrong.len())
        .filter(|&i| wrong[i])
        .filter(|&i| {
            let (a, b) = (o.normals[i], truth[i]);
            (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).abs() < 0.5
        })
        .count();
    println!("  wrong with |n . n_true| < 0.5 (the normal itself off by more than 60 degrees): {bad}");
    if std::env::var("EN_PATCHES").is_ok() {
        let mixed: Vec<(usize, usize, usize)> = (0..m)
            .filter(|&p| per[p].1 > 0)
            .map(|p| {
                let good_wrong = (0..wrong.len())
                    .filter(|&i| patch[i] == p && wrong[i])
                    .filter(|&i| {
                        let (a, b) = (o.normals[i], truth[i]);
                        (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).abs() >= 0.5
                    })
                    .count();
                (per[p].0, per[p].1, good_wrong)
            })
            .collect();
        println!("  patches with wrong points (size, wrong, wrong with a good normal): {mixed:?}");
    }
    {
        // single flips from the present signs: the energy change of each patch and its truth
        let w = m + 1;
        let (mut down_wrong, mut up_wrong, mut down_right) = (0, 0, 0);
        for p in 0..m {
            let d: f64 = -4.0 * (0..w).filter(|&q| q != p).map(|q| h[p * w + q]).sum::<f64>();
            let truly_wrong = oracle[p] < 0.0;
            match (truly_wrong, d < 0.0) {
                (true, true) => down_wrong += per[p].0,
                (true, false) => up_wrong += per[p].0,
                (false, true) => down_right += per[p].0,
                _ => {}
            }
        }
        println!("  points in single flips: wrong patches downhill {down_wrong}, uphill {up_wrong}; right patches downhill {down_right}");
    }
    if std::env::var("EN_VOTE").is_ok() {
        // the side the rest of the neighbourhood lies on: outward normals point away from it
        let tau: f64 = std::env::var("EN_VOTE").unwrap().parse().unwrap_or(0.3);
        let mut vote = vec![0.0; m + 1];
        let mut count = vec![0.0f64; m + 1];
        let pts = &prep.centres;
        for i in 0..wrong.len() {
            for &j in &hoods.knn[i * hoods.kmax..(i + 1) * hoods.kmax] {
                if patch[j] == patch[i] {
                    continue;
                }
                let d = [0, 1, 2].map(|k| pts[3 * j + k] - pts[3 * i + k]);
                let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let a = (o.normals[i][0] * d[0] + o.normals[i][1] * d[1] + o.normals[i][2] * d[2])
                    / r.max(1e-300);
                if a.abs() > tau {
                    vote[patch[i]] += a.signum();
                    count[patch[i]] += 1.0;
                }
            }
        }
        let list: Vec<String> = (0..m)
            .filter(|&p| vote[p] > 0.0 || oracle[p] < 0.0)
            .map(|p| {
                format!(
                    "{}{}:{:.2}",
                    if oracle[p] < 0.0 { "W" } else { "r" },
                    per[p].0,
                    vote[p] / count[p].max(1.0)
                )
            })
            .collect();
        println!("  {}", list.join(" "));
        let (mut good, mut bad, mut missed) = (0, 0, 0);
        for p in 0..m {
            match (oracle[p] < 0.0, vote[p] > 0.0) {
                (true, true) => good += per[p].0,
                (false, true) => bad += per[p].0,
                (true, false) => missed += per[p].0,
                _ => {}
            }
        }
        println!("  neighbour-side vote (tau {tau}): points in wrong patches caught {good}, missed {missed}; in right patches turned {bad}");
    }
    let fixed_wrong = per[m].1;
    let movable_wrong: usize = per[..m].iter().map(|x| x.1).sum();
    let ideal: usize = per[..m].iter().map(|x| x.1.min(x.0 - x.1)).sum::<usize>() + fixed_wrong;
    println!(
        "  wrong {} (fixed {fixed_wrong}, movable {movable_wrong}); oracle turns {} patches, E {:.4} vs now {:.4}; \
         best with these patches {} wrong",
        wrong.iter().filter(|&&w| w).count(),
        oracle.iter().filter(|&&v| v < 0.0).count(),
        energy(&h, &oracle),
        energy(&h, &vec![1.0; m + 1]),
        ideal
    );
    let mut normals = o.normals.clone();
    let t0 = Instant::now();
    let e = flip_by_energy(&Solo, &prep, &hoods, &mut normals).unwrap();
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "{}: N {} off {} agreement before {before:.4} after {:.4}; {e:?}; {secs:.2} s",
        args[1],
        truth.len(),
        off.side.len(),
        agree(&normals)
    );
}
