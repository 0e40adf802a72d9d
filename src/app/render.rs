//! `volspline render`: a solid ray-cast into a PNG picture, and the previews `fit` and `contours`
//! write. Every rank loads the solid; the lattice of the ray caster ([`crate::frep::raycast`]) is
//! evaluated with its nodes dealt round the ranks and summed; the rows of pixels are dealt round
//! the ranks (row j to rank j mod P) and threaded within; rank 0 gathers them, colours them and
//! writes the PNG. A pixel's colour depends on its ray alone (and, for curvature colouring, on
//! the picture's curvature scale, computed on rank 0 from every pixel), so any number of ranks
//! and threads gives the same picture.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::finite::reach;
use super::progress::Progress;
use super::report::Report;
use super::stages::{Stage, Stages};
use crate::cli::{RenderArgs, ViewArgs};
use crate::error::{Error, Result};
use crate::frep::curvature::{check_curvature_reach, curvature};
use crate::frep::raycast::{
    first_root, pixel_colour, shade, Axis, Camera, Colouring, Lattice, View, BACKGROUND,
};
use crate::frep::{Expr, Implicit, ModelSolid, Rescaled, Syntax};
use crate::io::contour_model_file::{self, read_contour_model};
use crate::io::h5::format_of;
use crate::io::model_file::read_model;
use crate::par::{agree, on_root, Comm};

/// An RGB picture, rows from the top, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Picture {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<u8>,
    /// Pixels whose ray met the solid.
    pub hits: usize,
}

/// The side of the square previews written by `fit` and `contours`.
pub const PREVIEW_SIZE: usize = 256;

/// The solid named on the command line: a model file of `fit` (evaluated at single points with
/// [`ModelSolid`]) or of `contours`, or an FRep expression over models and carriers ([`Expr`]).
pub fn load_solid(arg: &str) -> Result<Box<dyn Implicit>> {
    let syntax = Syntax::parse(arg)?;
    let Some(path) = syntax.as_model() else {
        return Ok(Box::new(Expr::load(&syntax)?));
    };
    if format_of(path).is_ok_and(|f| f == contour_model_file::FORMAT) {
        return Ok(Box::new(read_contour_model(path)?));
    }
    Ok(Box::new(ModelSolid::new(read_model(path)?)))
}

/// The view of the command-line options.
pub fn view_of(v: &ViewArgs) -> View {
    View {
        azimuth: v.azimuth,
        elevation: v.elevation,
        distance: v.distance,
        width: v.size.0,
        height: v.size.1,
        up: v.up,
    }
}

/// The bounds of `solid`, refused unless finite with positive extent.
fn checked_bounds(solid: &dyn Implicit) -> Result<([f64; 3], [f64; 3])> {
    let (lo, hi) = solid.bounds();
    if (0..3).all(|d| lo[d].is_finite() && hi[d].is_finite() && lo[d] < hi[d]) {
        Ok((lo, hi))
    } else {
        Err(Error::Usage(format!("the solid's bounds {lo:?} .. {hi:?} are not a box with positive extent")))
    }
}

/// One pixel as a rank computes it: hit (1) or not (0), light, specular, mean curvature.
type Sample = [f64; 4];

/// Ray-casts `solid` with `view`; the picture on rank 0, None elsewhere. Collective.
pub fn render(
    comm: &dyn Comm,
    solid: &dyn Implicit,
    view: &View,
    colouring: Colouring,
) -> Result<Option<Picture>> {
    let bounds = agree(comm, checked_bounds(solid))?;
    if colouring == Colouring::Curvature {
        check_curvature_reach(reach(&bounds.0).max(reach(&bounds.1)), "--color curvature")?;
    }
    // cast in the solid's own unit, so that data at any scale give the picture of unit scale
    let scaled = Rescaled::of(solid, bounds);
    let (solid, view) = (&scaled as &dyn Implicit, &scaled_view(view, scaled.unit));
    let bounds = checked_bounds(solid)?;
    let (rank, size) = (comm.rank(), comm.size());
    // the lattice: nodes dealt round the ranks, the others' left zero and the sum taken
    let cells = Lattice::cells_for(bounds);
    let nodes = (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1);
    let mut values = vec![0.0; nodes];
    values.par_iter_mut().enumerate().filter(|(q, _)| q % size == rank).for_each(|(q, v)| {
        *v = solid.value(Lattice::node(bounds, cells, q));
    });
    comm.sum_f64(&mut values);
    let mut lattice = Lattice::new(bounds, cells, &values);
    lattice.look_closely(&solid.surface_points());

    let camera = Camera::frame(bounds, view);
    let (w, h) = (view.width, view.height);
    let rows: Vec<usize> = (rank..h).step_by(size).collect();
    // rank 0's rows done, for the progress bar
    let progress = Progress::new("render", comm);
    let done = AtomicUsize::new(0);
    progress.update(0, rows.len());
    let mine: Vec<Sample> = rows
        .par_iter()
        .map(|&j| {
            let row: Vec<Sample> = (0..w)
                .map(|i| {
                    let d = camera.ray(i, j);
                    let Some(t) = first_root(solid, &lattice, camera.eye, d) else { return [0.0; 4] };
                    let x: [f64; 3] = std::array::from_fn(|a| camera.eye[a] + t * d[a]);
                    let (light, specular) = shade(&camera, solid.gradient(x), d);
                    let mean = match colouring {
                        Colouring::Curvature => curvature(solid, x).mean,
                        Colouring::Shading => f64::NAN,
                    };
                    [1.0, light, specular, mean]
                })
                .collect();
            progress.update(done.fetch_add(1, Ordering::Relaxed) + 1, rows.len());
            row
        })
        .flatten_iter()
        .collect();
    let gathered = comm.gather_values(0, &mine);
    let Some(parts) = gathered else { return Ok(None) };
    let mut samples = vec![[0.0; 4]; w * h];
    for (r, part) in parts.iter().enumerate() {
        for (n, j) in (r..h).step_by(size).enumerate() {
            samples[j * w..(j + 1) * w].copy_from_slice(&part[n * w..(n + 1) * w]);
        }
    }
    let scale = match colouring {
        Colouring::Curvature => curvature_scale(&samples),
        Colouring::Shading => f64::NAN,
    };
    let mut rgb = Vec::with_capacity(3 * w * h);
    for s in &samples {
        let c = if s[0] == 0.0 {
            BACKGROUND
        } else {
            let curv = (colouring == Colouring::Curvature).then(|| s[3] / scale);
            pixel_colour(s[1], s[2], curv)
        };
        rgb.extend_from_slice(&c);
    }
    let hits = samples.iter().filter(|s| s[0] != 0.0).count();
    Ok(Some(Picture { width: w, height: h, rgb, hits }))
}

/// The 95th percentile of |mean curvature| over the pixels that hit (1 if none or all zero).
fn curvature_scale(samples: &[Sample]) -> f64 {
    let mut m: Vec<f64> =
        samples.iter().filter(|s| s[0] != 0.0 && s[3].is_finite()).map(|s| s[3].abs()).collect();
    if m.is_empty() {
        return 1.0;
    }
    m.sort_unstable_by(f64::total_cmp);
    let v = m[((m.len() - 1) as f64 * 0.95) as usize];
    if v > 0.0 {
        v
    } else {
        1.0
    }
}

/// Writes `pic` as an 8-bit RGB PNG.
pub fn write_png(path: &Path, pic: &Picture) -> Result<()> {
    let io = |e: std::io::Error| Error::io(path, &e);
    let png_err = |e: png::EncodingError| Error::Io { path: path.into(), reason: e.to_string() };
    let file = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
    let mut enc = png::Encoder::new(file, pic.width as u32, pic.height as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(png_err)?;
    writer.write_image_data(&pic.rgb).map_err(png_err)?;
    writer.finish().map_err(png_err)
}

/// Refuses an output path whose name is not a `.png` file's (where it may be written is
/// [`super::preflight::writable_file`]'s check).
fn check_png_name(path: &Path) -> Result<()> {
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(Error::Usage(format!("--out {}: expected the name of a .png file", path.display())));
    }
    Ok(())
}

/// Renders `solid` with `view` and writes it to `path` from rank 0 (staged with the run's other
/// outputs), timing the render and write stages; returns the pixels whose ray met the solid, on
/// every rank. Collective.
pub fn write_picture(
    comm: &dyn Comm,
    solid: &dyn Implicit,
    view: &View,
    colouring: Colouring,
    path: &Path,
    stages: &mut Stages,
) -> Result<usize> {
    let pic = stages.time(Stage::Render, || render(comm, solid, view, colouring))?;
    stages.time(Stage::Write, || {
        on_root(comm, || match &pic {
            Some(p) => crate::io::write_atomically(path, |tmp| write_png(tmp, p)),
            None => Ok(()),
        })
    })?;
    let mut hits = [pic.map_or(0.0, |p| p.hits as f64)];
    comm.broadcast_f64(0, &mut hits);
    Ok(hits[0] as usize)
}

/// The default view of a preview: from the upper front left, y up.
pub fn preview_view() -> View {
    View {
        azimuth: 30.0,
        elevation: 20.0,
        distance: None,
        width: PREVIEW_SIZE,
        height: PREVIEW_SIZE,
        up: Axis::Y,
    }
}

/// `view` with its camera distance in the unit of a [`Rescaled`] solid.
fn scaled_view(view: &View, unit: f64) -> View {
    View { distance: view.distance.map(|d| d / unit), ..*view }
}

/// Why a picture with `hits` pixels on the solid shows little of it, when the view is the cause
/// or nothing was hit: the solid's box smaller than a pixel from the camera, the camera inside
/// the solid (every ray starts inside), or no ray meeting the solid.
fn view_warning(solid: &dyn Implicit, view: &View, hits: usize) -> Option<String> {
    let pixels = view.width * view.height;
    let scaled = Rescaled::of(solid, checked_bounds(solid).ok()?);
    let bounds = checked_bounds(&scaled).ok()?;
    let camera = Camera::frame(bounds, &scaled_view(view, scaled.unit));
    // the camera's lengths in the solid's units again, for the messages
    let (distance, radius) = (camera.distance * scaled.unit, camera.radius * scaled.unit);
    // the half-width of a pixel at the centre's distance
    let pixel = distance * camera.tan_half / view.height as f64;
    if hits == 0 && radius < pixel {
        return Some(format!(
            "no ray met the solid: from the camera's distance {distance:.4e} the solid's box (radius \
             {radius:.4e}) spans less than a pixel; leave out --distance to fill the view"
        ));
    }
    if hits == pixels && distance < radius && scaled.value(camera.eye) >= 0.0 {
        return Some(format!(
            "the camera (at distance {distance:.4e} from the centre of the solid's box) is inside the solid, \
             so every ray starts inside and the picture shows no surface; a --distance above {radius:.4e} \
             puts it outside the box"
        ));
    }
    (hits == 0).then(|| {
        "no ray met the solid, so the picture shows the background alone: the solid is empty in its box \
         (f < 0 wherever the rays sampled it) or thinner than the rays' steps"
            .to_string()
    })
}

/// Runs `volspline render`. Collective.
pub fn run(a: &RenderArgs, comm: &dyn Comm, threads: usize) -> Result<()> {
    let mut stages = Stages::default();
    // the models an expression reads (a text that parses as none is refused by the reader below)
    let models = Syntax::parse(&a.model).map(|s| s.models()).unwrap_or_default();
    let inputs: Vec<&Path> = models.iter().map(PathBuf::as_path).collect();
    on_root(comm, || {
        check_png_name(&a.out)?;
        super::preflight::writable_file(&a.out, "a .png file", a.timings.as_deref(), &inputs)
    })?;
    let solid = stages.time(Stage::Read, || agree(comm, load_solid(&a.model)))?;
    let view = view_of(&a.view);
    let hits = write_picture(comm, solid.as_ref(), &view, a.view.color, &a.out, &mut stages)?;
    if comm.rank() == 0 {
        if let Some(w) = view_warning(solid.as_ref(), &view, hits) {
            crate::note!("volspline: warning: {w}");
        }
    }
    let mut r = Report::new("render", Path::new(&a.model));
    r.line(format!(
        "{} x {} pixels, azimuth {} deg, elevation {} deg, colouring {:?}; {hits} pixels on the solid",
        view.width, view.height, view.azimuth, view.elevation, a.view.color
    ));
    r.figure("pixels_on_solid", hits);
    r.line(format!("ranks = {}, threads per rank = {threads}", comm.size()));
    r.figure("model", &a.model);
    r.figure("width", view.width);
    r.figure("height", view.height);
    r.figure("ranks", comm.size());
    r.figure("threads", threads);
    r.output(&a.out);
    r.finish(comm, &stages, &|_| Vec::new(), a.timings.as_deref())?;
    Ok(())
}
