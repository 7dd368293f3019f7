//! Filmstrips of scenes: [`render_scene`] steps a [`Scene`] and draws, into one PNG, a row of
//! orthographic side views (x–z) and a row of top views (x–y) at `frames` instants from t = 0 to
//! t = T (one every T/(frames − 1) s), with every collider drawn as its outline, and below them
//! plots of the centre-of-mass height, its speed and the energy over time (plotters).
//!
//! Outlines: a convex collider (sphere, box, capsule, cylinder, convex hull) is drawn as its exact
//! silhouette, the support points of the shape in directions around the view plane; a triangle
//! mesh or height field by its vertices (the upper profile in the side view, the hull of the
//! vertices in the top view and for moving meshes); a half-space as its trace, the ground line.
//! Every frame has the same scale, and is centred on what moves in it, so that a body that
//! travels stays in view; the scale bar says how long a metre is.

use crate::io::scene::{Scene, SceneError};
use crate::math::Vec3;
use crate::Data;
use parry3d_f64::math::Vector;
use plotters::prelude::*;
use std::path::Path;
use thiserror::Error;

/// What to draw.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Number of frames (≥ 2): t = 0, T/(frames − 1), …, T.
    pub frames: usize,
    /// Simulated time T (s); `None`: the scene's duration.
    pub duration: Option<f64>,
    /// Side of one frame (px).
    pub frame_size: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self { frames: 8, duration: None, frame_size: 220 }
    }
}

/// Why a filmstrip could not be made.
#[derive(Debug, Error)]
pub enum RenderError {
    /// Bad options (frames, duration, output name).
    #[error("{0}")]
    Options(String),
    /// The scene failed to step.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Drawing or writing the image failed.
    #[error("cannot draw {file}: {message}")]
    Draw {
        /// Output file.
        file: String,
        /// plotters' message.
        message: String,
    },
}

/// What was drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSummary {
    /// Frame times (s).
    pub frame_times: Vec<f64>,
    /// Steps simulated.
    pub steps: usize,
    /// Image size (px).
    pub size: (u32, u32),
}

/// A 2-D outline in view coordinates (m): a closed polygon or an open polyline.
#[derive(Clone, Debug, PartialEq)]
struct Outline {
    points: Vec<(f64, f64)>,
    closed: bool,
    moving: bool,
}

/// A view: the two world axes that become the horizontal and vertical image axes.
#[derive(Clone, Copy)]
struct View {
    u: Vec3,
    w: Vec3,
}

const SIDE: View = View { u: Vec3::new(1.0, 0.0, 0.0), w: Vec3::new(0.0, 0.0, 1.0) };
const TOP: View = View { u: Vec3::new(1.0, 0.0, 0.0), w: Vec3::new(0.0, 1.0, 0.0) };

/// Support-point directions per outline: enough for a smooth capsule or sphere silhouette.
const SILHOUETTE_SAMPLES: usize = 48;

fn vec3(v: Vector) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// Outlines of every collider of the world, as seen in `view`.
fn outlines(scene: &Scene, view: View) -> Vec<Outline> {
    let mut out = Vec::new();
    let project = |p: &Vec3| (p.dot(&view.u), p.dot(&view.w));
    for c in scene.world.collision().colliders() {
        let moving = !c.attachment().is_static();
        let (shape, pose) = c.parry_shape();
        if let Some(support) = shape.as_support_map() {
            let points = (0..SILHOUETTE_SAMPLES)
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / SILHOUETTE_SAMPLES as f64;
                    let d = view.u * a.cos() + view.w * a.sin();
                    project(&vec3(support.support_point(pose, Vector::new(d.x, d.y, d.z))))
                })
                .collect();
            out.push(Outline { points, closed: true, moving });
        } else if let Some(half) = shape.as_halfspace() {
            // The trace of the plane n·(p − p0) = 0 in the view plane, if the plane is not parallel to it.
            let n = vec3(pose.rotation * half.normal);
            let (nu, nw) = (n.dot(&view.u), n.dot(&view.w));
            if nu.hypot(nw) > 1e-6 {
                let p0 = project(&vec3(pose.translation));
                let d = (-nw, nu);
                let far = 1e4;
                let line = vec![(p0.0 - far * d.0, p0.1 - far * d.1), (p0.0 + far * d.0, p0.1 + far * d.1)];
                out.push(Outline { points: line, closed: false, moving });
            }
        } else {
            let local: Vec<Vector> = if let Some(mesh) = shape.as_trimesh() {
                mesh.vertices().to_vec()
            } else if let Some(field) = shape.as_heightfield() {
                field.triangles().flat_map(|t| [t.a, t.b, t.c]).collect()
            } else {
                Vec::new()
            };
            let points: Vec<(f64, f64)> =
                local.iter().map(|p| project(&vec3(pose.transform_point(*p)))).collect();
            if points.is_empty() {
                continue;
            }
            if !moving && view.w.z.abs() > 0.5 {
                out.push(Outline { points: upper_profile(&points, 200), closed: false, moving });
            } else {
                out.push(Outline { points: convex_hull(points), closed: true, moving });
            }
        }
    }
    out
}

/// The highest point in each of `bins` columns of the points: a terrain's profile.
fn upper_profile(points: &[(f64, f64)], bins: usize) -> Vec<(f64, f64)> {
    let (lo, hi) =
        points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let width = (hi - lo).max(1e-9);
    let mut top = vec![f64::NEG_INFINITY; bins];
    for p in points {
        let k = (((p.0 - lo) / width) * (bins - 1) as f64).round() as usize;
        top[k] = top[k].max(p.1);
    }
    top.iter()
        .enumerate()
        .filter(|(_, h)| h.is_finite())
        .map(|(k, h)| (lo + width * k as f64 / (bins - 1) as f64, *h))
        .collect()
}

/// Andrew's monotone chain: the convex hull, counter-clockwise.
fn convex_hull(mut points: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let cross =
        |o: (f64, f64), a: (f64, f64), b: (f64, f64)| (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0);
    let mut hull: Vec<(f64, f64)> = Vec::with_capacity(points.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &(f64, f64)>> =
            if pass == 0 { Box::new(points.iter()) } else { Box::new(points.iter().rev()) };
        for &p in iter {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// Bounding box (min u, min w, max u, max w) of the moving outlines, if any.
fn moving_box(outlines: &[Outline]) -> Option<(f64, f64, f64, f64)> {
    outlines.iter().filter(|o| o.moving).flat_map(|o| o.points.iter()).fold(None, |b, p| {
        let (a, c, d, e) = b.unwrap_or((p.0, p.1, p.0, p.1));
        Some((a.min(p.0), c.min(p.1), d.max(p.0), e.max(p.1)))
    })
}

/// One sample of the time series.
#[derive(Clone, Copy, Debug, Default)]
struct Sample {
    time: f64,
    height: f64,
    speed: f64,
    energy: f64,
    kinetic: f64,
}

fn sample(scene: &mut Scene, datas: &mut [Data]) -> Sample {
    let world = &mut scene.world;
    let (mut moment, mut mass) = (Vec3::zeros(), 0.0);
    for (i, data) in datas.iter_mut().enumerate() {
        let mb = world.multibody(i);
        let m = mb.model().total_mass();
        if let Ok(c) = crate::algorithms::center_of_mass(mb.model(), data, &mb.state.q) {
            moment += c * m;
            mass += m;
        }
    }
    let momentum = world.linear_momentum();
    let mass = mass.max(f64::MIN_POSITIVE);
    Sample {
        time: world.time(),
        height: moment.z / mass,
        speed: momentum.norm() / mass,
        energy: world.total_energy(),
        kinetic: world.kinetic_energy(),
    }
}

/// Steps `scene` for the duration and draws its filmstrip and plots into the PNG file `out`.
pub fn render_scene(
    scene: &mut Scene,
    options: &RenderOptions,
    out: &Path,
) -> Result<RenderSummary, RenderError> {
    if options.frames < 2 || options.frames > 64 {
        return Err(RenderError::Options(format!("frames must be within 2..=64, got {}", options.frames)));
    }
    if !out.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(RenderError::Options(format!("{}: the output file must end in .png", out.display())));
    }
    let duration = options.duration.unwrap_or(scene.duration);
    if !(duration.is_finite() && duration > 0.0) {
        return Err(RenderError::Options(format!("duration must be positive, got {duration}")));
    }
    let dt = scene.world.options().dt;
    let steps = (duration / dt).round().max(1.0) as usize;
    let frame_steps: Vec<usize> =
        (0..options.frames).map(|k| (k * steps + (options.frames - 1) / 2) / (options.frames - 1)).collect();
    let mut datas: Vec<Data> =
        (0..scene.world.multibody_count()).map(|i| Data::new(scene.world.multibody(i).model())).collect();

    // The world's collider poses are updated by a step; refresh them for the initial frame.
    let mut frames: Vec<(f64, Vec<Outline>, Vec<Outline>)> = Vec::new();
    let mut series = vec![sample(scene, &mut datas)];
    let mut next = 0;
    for step in 0..=steps {
        if step > 0 {
            let time = scene.world.time();
            scene.world.step().map_err(|source| SceneError::Step {
                step: step as u64,
                time,
                source: Box::new(source),
            })?;
            series.push(sample(scene, &mut datas));
        }
        while next < frame_steps.len() && frame_steps[next] == step {
            if step == 0 {
                scene.world.refresh_collision().map_err(|source| SceneError::Step {
                    step: 0,
                    time: 0.0,
                    source: Box::new(source),
                })?;
            }
            frames.push((scene.world.time(), outlines(scene, SIDE), outlines(scene, TOP)));
            next += 1;
        }
    }
    let size = draw(scene, options, &frames, &series, out)?;
    Ok(RenderSummary { frame_times: frames.iter().map(|f| f.0).collect(), steps, size })
}

type Frame = (f64, Vec<Outline>, Vec<Outline>);

/// A named line of a plot: (legend, points (t, value), colour).
type Curve<'a> = (&'a str, Vec<(f64, f64)>, RGBColor);

fn draw(
    scene: &Scene,
    options: &RenderOptions,
    frames: &[Frame],
    series: &[Sample],
    out: &Path,
) -> Result<(u32, u32), RenderError> {
    crate::plot::register_fonts();
    let cell = options.frame_size;
    let label = 70u32;
    let (title_h, plots_h) = (34u32, 260u32);
    let width = label + cell * frames.len() as u32;
    let height = title_h + 2 * cell + plots_h;
    let fail = |e: &dyn std::fmt::Display| RenderError::Draw {
        file: out.display().to_string(),
        message: e.to_string(),
    };
    let root = BitMapBackend::new(out, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let font = ("sans-serif", 16).into_font();
    let title = format!(
        "{} — {} s, {} frames",
        scene.name,
        fmt_time(series.last().map_or(0.0, |s| s.time)),
        frames.len()
    );
    root.draw(&Text::new(title, (8, 8), ("sans-serif", 20).into_font())).map_err(|e| fail(&e))?;

    // One scale for every frame of a row: the largest moving extent, with a margin.
    for (row, (name, pick)) in [("side x–z", 1usize), ("top x–y", 2)].into_iter().enumerate() {
        let y0 = title_h + row as u32 * cell;
        root.draw(&Text::new(name, (6, (y0 + cell / 2) as i32), font.clone())).map_err(|e| fail(&e))?;
        let views: Vec<&Vec<Outline>> = frames.iter().map(|f| if pick == 1 { &f.1 } else { &f.2 }).collect();
        let extent = views
            .iter()
            .filter_map(|v| moving_box(v))
            .map(|b| (b.2 - b.0).max(b.3 - b.1))
            .fold(0.5f64, f64::max)
            * 1.25;
        let scale = cell as f64 / extent; // px per m
        for (k, outlines) in views.iter().enumerate() {
            let x0 = label + k as u32 * cell;
            let area = root.clone().shrink((x0, y0), (cell, cell));
            let centre = moving_box(outlines).map_or((0.0, 0.0), |b| (0.5 * (b.0 + b.2), 0.5 * (b.1 + b.3)));
            let to_px = |p: &(f64, f64)| {
                let x = (cell as f64 / 2.0 + (p.0 - centre.0) * scale).clamp(-1e5, 1e5);
                let y = (cell as f64 / 2.0 - (p.1 - centre.1) * scale).clamp(-1e5, 1e5);
                (x.round() as i32, y.round() as i32)
            };
            for o in outlines.iter().filter(|o| !o.moving).chain(outlines.iter().filter(|o| o.moving)) {
                let px: Vec<(i32, i32)> = o.points.iter().map(to_px).collect();
                if o.closed && px.len() >= 3 {
                    let fill = if o.moving { RGBColor(170, 200, 235) } else { RGBColor(215, 215, 215) };
                    area.draw(&Polygon::new(px.clone(), fill.filled())).map_err(|e| fail(&e))?;
                    let mut ring = px.clone();
                    ring.push(px[0]);
                    area.draw(&PathElement::new(ring, RGBColor(40, 60, 110).stroke_width(1)))
                        .map_err(|e| fail(&e))?;
                } else {
                    area.draw(&PathElement::new(px, RGBColor(90, 70, 50).stroke_width(2)))
                        .map_err(|e| fail(&e))?;
                }
            }
            area.draw(&Rectangle::new([(0, 0), (cell as i32 - 1, cell as i32 - 1)], RGBColor(180, 180, 180)))
                .map_err(|e| fail(&e))?;
            if row == 0 {
                let t = frames[k].0;
                area.draw(&Text::new(format!("t = {} s", fmt_time(t)), (6, 4), font.clone()))
                    .map_err(|e| fail(&e))?;
            }
            if k == 0 {
                // Scale bar: the largest of 0.1, 0.2, 0.5, 1, 2, 5 … m shorter than a third of the frame.
                let bar = nice_length(extent / 3.0);
                let len = (bar * scale).round() as i32;
                let y = cell as i32 - 12;
                area.draw(&PathElement::new(vec![(8, y), (8 + len, y)], BLACK.stroke_width(2)))
                    .map_err(|e| fail(&e))?;
                area.draw(&Text::new(format!("{bar} m"), (10 + len, y - 8), font.clone()))
                    .map_err(|e| fail(&e))?;
            }
        }
    }

    // Plots: centre-of-mass height, its speed, energy.
    let plots = root.clone().shrink((0, title_h + 2 * cell), (width, plots_h));
    let panels = plots.split_evenly((1, 3));
    let t_end = series.last().map_or(1.0, |s| s.time).max(1e-9);
    let curves: [(&str, Vec<Curve>); 3] = [
        ("centre-of-mass height (m)", vec![("z", series.iter().map(|s| (s.time, s.height)).collect(), BLUE)]),
        (
            "centre-of-mass speed (m/s)",
            vec![("|v|", series.iter().map(|s| (s.time, s.speed)).collect(), RED)],
        ),
        (
            "energy (J)",
            vec![
                ("total", series.iter().map(|s| (s.time, s.energy)).collect(), BLACK),
                ("kinetic", series.iter().map(|s| (s.time, s.kinetic)).collect(), RGBColor(0, 140, 0)),
            ],
        ),
    ];
    for (panel, (caption, lines)) in panels.iter().zip(curves) {
        let values = lines.iter().flat_map(|l| l.1.iter().map(|p| p.1)).filter(|v| v.is_finite());
        let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
        let pad = ((hi - lo) * 0.08).max(1e-6 * hi.abs().max(1.0));
        let mut chart = ChartBuilder::on(panel)
            .caption(caption, ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..t_end, (lo - pad)..(hi + pad))
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .label_style(("sans-serif", 12))
            .light_line_style(TRANSPARENT)
            .draw()
            .map_err(|e| fail(&e))?;
        let several = lines.len() > 1;
        for (name, points, color) in lines {
            let drawn =
                chart.draw_series(LineSeries::new(points, color.stroke_width(2))).map_err(|e| fail(&e))?;
            if several {
                drawn
                    .label(name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2)));
            }
        }
        if several {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(RGBColor(200, 200, 200))
                .label_font(("sans-serif", 12))
                .draw()
                .map_err(|e| fail(&e))?;
        }
    }
    root.present().map_err(|e| fail(&e))?;
    Ok((width, height))
}

fn fmt_time(t: f64) -> String {
    let s = format!("{t:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() { "0" } else { s }.to_string()
}

/// The largest 1, 2 or 5 × 10ⁿ not above `x` (x > 0).
fn nice_length(x: f64) -> f64 {
    let p = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0].into_iter().map(|m| m * p).find(|v| *v <= x).unwrap_or(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn convex_hull_of_a_square_with_inner_points() {
        let pts = vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.5, 0.5), (0.2, 0.7)];
        let hull = convex_hull(pts);
        assert_eq!(hull, vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
    }

    #[test]
    fn profile_and_scale_bar() {
        let p = upper_profile(&[(0.0, 1.0), (0.0, 2.0), (1.0, 3.0)], 2);
        assert_eq!(p, vec![(0.0, 2.0), (1.0, 3.0)]);
        assert_eq!(nice_length(0.7), 0.5);
        assert_eq!(nice_length(3.0), 2.0);
        assert_eq!(fmt_time(0.5), "0.5");
        assert_eq!(fmt_time(0.0), "0");
    }
}
