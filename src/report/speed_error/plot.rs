//! The speed–error plot: one log–log panel per scene, error against cost, one curve per
//! configuration, the scene's Pareto front in black, MuJoCo's points on the pendulum panel.

use super::types::{measures, pareto_front, ReportError, SpeedErrorReport, SCENES};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Draws the report into a PNG and an SVG.
pub(crate) fn plot(report: &SpeedErrorReport, png: &Path, svg: &Path) -> Result<(), ReportError> {
    crate::plot::register_fonts();
    let size = (1800, 1000);
    let err = |path: &Path| {
        let path = path.display().to_string();
        move |e: String| ReportError::Plot { path: path.clone(), message: e }
    };
    {
        let root = BitMapBackend::new(png, size).into_drawing_area();
        draw(report, &root).map_err(err(png))?;
        root.present().map_err(|e| e.to_string()).map_err(err(png))?;
    }
    {
        let root = SVGBackend::new(svg, size).into_drawing_area();
        draw(report, &root).map_err(err(svg))?;
        root.present().map_err(|e| e.to_string()).map_err(err(svg))?;
    }
    Ok(())
}

/// Smallest error drawn (errors at rounding level are clamped here on a log axis).
const FLOOR: f64 = 1e-15;

fn draw<DB: DrawingBackend>(report: &SpeedErrorReport, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let scenes: Vec<&str> =
        SCENES.iter().map(|s| s.scene).filter(|s| report.rows.iter().any(|r| r.scene == *s)).collect();
    let title = root
        .titled("gelenk: error against cost (log–log), Pareto front in black", ("sans-serif", 26))
        .map_err(|e| e.to_string())?;
    let panels = title.split_evenly((2, 4));
    for (panel, scene) in panels.iter().zip(scenes) {
        draw_panel(report, panel, scene)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    report: &SpeedErrorReport,
    area: &DrawingArea<DB, Shift>,
    scene: &str,
) -> Result<(), String> {
    let rows: Vec<_> = report.rows.iter().filter(|r| r.scene == scene).collect();
    let mut points: Vec<(f64, f64)> = rows.iter().map(|r| (r.cost_us, r.error.max(FLOOR))).collect();
    let peers: Vec<(f64, f64, &str)> = if scene == "pendulum5" {
        report.mujoco.iter().map(|p| (p.cost_us, p.error.max(FLOOR), p.integrator.as_str())).collect()
    } else {
        Vec::new()
    };
    points.extend(peers.iter().map(|p| (p.0, p.1)));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for &(x, y) in &points {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let (x0, x1, y0, y1) = (x0 / 2.0, x1 * 2.0, y0 / 5.0, y1 * 5.0);
    let mut chart = ChartBuilder::on(area)
        .caption(scene, ("sans-serif", 20))
        .margin(8)
        .x_label_area_size(38)
        .y_label_area_size(58)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("µs per simulated s")
        .y_desc(measures(scene).error)
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 13))
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()
        .map_err(|e| e.to_string())?;
    let mut configurations: Vec<&str> = Vec::new();
    for r in &rows {
        if !configurations.contains(&r.configuration.as_str()) {
            configurations.push(&r.configuration);
        }
    }
    for (k, cfg) in configurations.iter().enumerate() {
        let color = Palette99::pick(k).to_rgba();
        let mut curve: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.configuration == *cfg)
            .map(|r| (r.cost_us, r.error.max(FLOOR)))
            .collect();
        curve.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(curve.clone(), color.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(*cfg)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2)));
        chart
            .draw_series(curve.iter().map(|&p| Circle::new(p, 3, color.filled())))
            .map_err(|e| e.to_string())?;
    }
    if !peers.is_empty() {
        let mut names: Vec<&str> = Vec::new();
        for p in &peers {
            if !names.contains(&p.2) {
                names.push(p.2);
            }
        }
        for (k, name) in names.iter().enumerate() {
            let color = if k == 0 { RGBColor(120, 120, 120) } else { RGBColor(60, 60, 60) };
            let mut curve: Vec<(f64, f64)> =
                peers.iter().filter(|p| p.2 == *name).map(|p| (p.0, p.1)).collect();
            curve.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart
                .draw_series(LineSeries::new(curve.clone(), ShapeStyle::from(&color).stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(format!("MuJoCo {name}"))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], ShapeStyle::from(&color).stroke_width(2))
                });
            chart
                .draw_series(
                    curve.iter().map(|&p| TriangleMarker::new(p, 6, ShapeStyle::from(&color).filled())),
                )
                .map_err(|e| e.to_string())?;
        }
    }
    let ours: Vec<(f64, f64)> = rows.iter().map(|r| (r.cost_us, r.error.max(FLOOR))).collect();
    let front: Vec<(f64, f64)> = pareto_front(&ours).into_iter().map(|i| ours[i]).collect();
    // The front as a staircase: an error level is reached from its cost on.
    let mut stairs = Vec::new();
    for (i, p) in front.iter().enumerate() {
        if i > 0 {
            stairs.push((p.0, front[i - 1].1));
        }
        stairs.push(*p);
    }
    chart
        .draw_series(LineSeries::new(stairs, BLACK.stroke_width(3)))
        .map_err(|e| e.to_string())?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK.stroke_width(3)));
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 11))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .position(SeriesLabelPosition::LowerLeft)
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(())
}
