//! `volspline render` and the previews of `fit`, through the real binary: a reconstructed sphere
//! covers the disc of pixels its radius predicts, a rod thinner than the ray caster's lattice
//! shows whole, pictures are the same on 1, 2 and 3 ranks, and bad arguments give a clear error
//! and no file.

mod common;

use std::f64::consts::PI;
use std::path::Path;

use common::{bunny_subset, run, run_ok, temp_dir, write_xyz};

/// The pixels of an 8-bit RGB PNG: (width, height, rgb bytes).
fn read_png(path: &Path) -> (usize, usize, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width as usize, info.height as usize, buf)
}

const BACKGROUND: [u8; 3] = volspline::frep::raycast::BACKGROUND;

/// Points on the unit sphere, the six poles included so that the data's box is exactly [-1, 1]^3
/// (the camera looks at its centre, the origin).
fn sphere_points(n: usize) -> Vec<f64> {
    let golden = PI * (3.0 - 5f64.sqrt());
    let mut pts: Vec<f64> = (0..n)
        .flat_map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let s = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            [s * t.cos(), s * t.sin(), z]
        })
        .collect();
    pts.extend([1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0]);
    pts
}

#[test]
fn a_rendered_sphere_covers_the_disc_its_radius_predicts() {
    let dir = temp_dir("render-disc");
    let input = dir.join("sphere.xyz");
    write_xyz(&input, &sphere_points(300));
    let prefix = dir.join("s");
    run_ok(1, &["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "12"]);
    // fit wrote its preview
    let (pw, ph, prgb) = read_png(&dir.join("s.png"));
    assert_eq!((pw, ph), (256, 256));
    assert!(prgb.chunks_exact(3).any(|c| c != BACKGROUND));
    let pic = dir.join("disc.png");
    let (w, h, distance) = (121usize, 101usize, 5.0f64);
    let args = [
        "render",
        "s.model.h5",
        "--out",
        "disc.png",
        "--azimuth",
        "35",
        "--elevation",
        "-20",
        "--distance",
        "5",
        "--size",
        "121x101",
        "--up",
        "z",
    ];
    let mut full: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    full[1] = dir.join("s.model.h5").to_string_lossy().into_owned();
    full[3] = pic.to_string_lossy().into_owned();
    let refs: Vec<&str> = full.iter().map(|s| s.as_str()).collect();
    run_ok(1, &refs);
    let (pw, ph, rgb) = read_png(&pic);
    assert_eq!((pw, ph), (w, h));
    // the silhouette of a ball of radius 1 seen from distance D is a cone of half-angle asin(1/D);
    // in the image plane at unit distance (vertical half-size tan 15 deg = h / 2 pixels) a circle
    // of radius tan(asin(1 / D))
    let pixels_per_unit = 0.5 * h as f64 / 15f64.to_radians().tan();
    let radius = (1.0 / distance).asin().tan() * pixels_per_unit;
    let (mut inside, mut rim) = (0usize, 0usize);
    for j in 0..h {
        for i in 0..w {
            let x = i as f64 + 0.5 - 0.5 * w as f64;
            let y = 0.5 * h as f64 - j as f64 - 0.5;
            let rho = (x * x + y * y).sqrt();
            let hit = rgb[3 * (j * w + i)..3 * (j * w + i) + 3] != BACKGROUND;
            if (rho - radius).abs() <= 1.0 {
                rim += 1;
                continue;
            }
            assert_eq!(
                hit,
                rho < radius,
                "pixel ({i}, {j}) at {rho:.2} px from the centre, disc radius {radius:.2}"
            );
            inside += usize::from(hit);
        }
    }
    assert!(inside > 3000 && rim > 100, "{inside} {rim}");
}

#[test]
fn a_rod_thinner_than_a_cell_of_the_ray_casters_lattice_shows_whole() {
    // 800 points on a rod of radius 0.1 and length 10 along x: the ray caster's lattice has 48
    // cells along the box's longest side, 0.25 wide, and its nodes miss the rod (0.2 across);
    // the fit's grid of 200 nodes resolves it
    let dir = temp_dir("render-rod");
    let input = dir.join("rod.xyz");
    let golden = PI * (3.0 - 5f64.sqrt());
    let rod: Vec<f64> = (0..800)
        .flat_map(|i| {
            let (x, a) = (10.0 * (i as f64 + 0.5) / 800.0, golden * i as f64);
            [x, 0.1 * a.cos(), 0.1 * a.sin()]
        })
        .collect();
    write_xyz(&input, &rod);
    let prefix = dir.join("r");
    run_ok(2, &["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "200"]);
    // the preview (256 x 256, from azimuth 30 and elevation 20, y up) and a picture from the
    // side, square to the rod
    let side = dir.join("side.png");
    let model = dir.join("r.model.h5");
    run_ok(1, &["render", model.to_str().unwrap(), "--out", side.to_str().unwrap(), "--up", "z"]);
    for (pic, (columns, least)) in [(dir.join("r.png"), (150, 500)), (side, (180, 1200))] {
        let (w, h, rgb) = read_png(&pic);
        let hit: Vec<bool> = rgb.chunks_exact(3).map(|c| c != BACKGROUND).collect();
        let pixels = hit.iter().filter(|&&b| b).count();
        let spanned = (0..w).filter(|&i| (0..h).any(|j| hit[j * w + i])).count();
        // the rod seen whole: a long thin line of pixels (the picture of the lattice's nodes
        // alone had 9 pixels in two dots), no wider than a few pixels
        assert!(
            spanned >= columns && pixels >= least,
            "{}: {pixels} pixels over {spanned} columns",
            pic.display()
        );
        assert!(pixels <= 16 * spanned, "{}: {pixels} pixels over {spanned} columns", pic.display());
    }
}

#[test]
fn pictures_are_the_same_on_one_two_and_three_ranks() {
    let dir = temp_dir("render-ranks");
    let input = dir.join("bunny.xyz");
    write_xyz(&input, &bunny_subset(8, 3));
    let prefix = dir.join("b");
    run_ok(
        2,
        &["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "16", "--no-preview"],
    );
    assert!(!dir.join("b.png").exists(), "--no-preview wrote a preview");
    let model = dir.join("b.model.h5");
    for colour in ["shading", "curvature"] {
        let mut pictures = Vec::new();
        for ranks in [1, 2, 3] {
            let pic = dir.join(format!("{colour}{ranks}.png"));
            run_ok(
                ranks,
                &[
                    "render",
                    model.to_str().unwrap(),
                    "--out",
                    pic.to_str().unwrap(),
                    "--size",
                    "96x80",
                    "--color",
                    colour,
                    "--azimuth",
                    "-40",
                ],
            );
            pictures.push(read_png(&pic));
        }
        let covered = pictures[0].2.chunks_exact(3).filter(|c| *c != BACKGROUND).count();
        assert!(covered > 96 * 80 / 10, "{colour}: the bunny covers only {covered} pixels");
        assert!(
            pictures[1] == pictures[0] && pictures[2] == pictures[0],
            "{colour}: pictures differ between ranks"
        );
    }
}

#[test]
fn bad_arguments_give_a_clear_error_and_no_file() {
    let dir = temp_dir("render-bad");
    let pic = dir.join("p.png");
    let p = pic.to_str().unwrap();
    let garbage = dir.join("garbage.model.h5");
    std::fs::write(&garbage, b"not a model").unwrap();
    let missing = dir.join("missing.model.h5");
    for (args, says) in [
        (vec!["render", missing.to_str().unwrap(), "--out", p], "missing.model.h5"),
        (vec!["render", garbage.to_str().unwrap(), "--out", p], "garbage.model.h5"),
        (vec!["render", garbage.to_str().unwrap(), "--out", dir.join("p.jpg").to_str().unwrap()], ".png"),
        (vec!["render", garbage.to_str().unwrap(), "--out", "/nonexistent-dir/p.png"], "does not exist"),
        (vec!["render", garbage.to_str().unwrap(), "--out", p, "--size", "100"], "WIDTHxHEIGHT"),
        (vec!["render", garbage.to_str().unwrap(), "--out", p, "--elevation", "120"], "-90, 90"),
    ] {
        let out = run(2, &args);
        let text = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(text.contains(says), "{args:?}: the error does not say '{says}':\n{text}");
        assert!(
            std::fs::read_dir(&dir).unwrap().all(|e| {
                let name = e.unwrap().file_name();
                name == "garbage.model.h5"
            }),
            "{args:?} left a file behind"
        );
    }
}
