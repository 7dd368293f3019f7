//! `[[ground]]` entries: planes, slopes and height fields as static colliders.

use super::{pose, Builder};
use crate::io::scene::schema::{GroundKind, GroundSection};
use crate::io::scene::SceneError;
use crate::math::{Transform, Vec3};
use crate::model::Shape;
use crate::world::World;
use nalgebra::DMatrix;
use toml::Spanned;

/// Most samples a generated heightfield has (`samples = [nx, ny]`), 32 MiB of heights.
const MAX_HEIGHTFIELD_SAMPLES: usize = 1 << 22;

impl Builder<'_> {
    pub(super) fn ground(
        &mut self,
        world: &mut World,
        index: usize,
        g: &Spanned<GroundSection>,
    ) -> Result<(), SceneError> {
        let span = g.span();
        let g = g.get_ref();
        let err = |message: String| self.src.invalid(span.clone(), message);
        let frame = pose(g.position, g.rpy, g.quaternion).map_err(err)?;
        let material = self.material_of(&g.material)?;
        let name = g.name.clone().unwrap_or_else(|| format!("ground{index}"));
        let given = [
            ("normal", g.normal.is_some()),
            ("offset", g.offset.is_some()),
            ("angle_deg", g.angle_deg.is_some()),
            ("direction", g.direction.is_some()),
            ("size", g.size.is_some()),
            ("heights", g.heights.is_some()),
            ("samples", g.samples.is_some()),
            ("bump_height", g.bump_height.is_some()),
            ("bump_wavelength", g.bump_wavelength.is_some()),
        ];
        let (kind_name, allowed): (&str, &[&str]) = match g.kind {
            GroundKind::Plane => ("plane", &["normal", "offset"]),
            GroundKind::Slope => ("slope", &["angle_deg", "direction"]),
            GroundKind::Heightfield => (
                "heightfield",
                &["angle_deg", "direction", "size", "heights", "samples", "bump_height", "bump_wavelength"],
            ),
        };
        if let Some((key, _)) = given.iter().find(|(k, set)| *set && !allowed.contains(k)) {
            return Err(err(format!("`{key}` does not apply to kind = \"{kind_name}\"")));
        }
        let unit = |v: Vec3, what: &str| {
            let n = v.norm();
            if n > 1e-12 {
                Ok(v / n)
            } else {
                Err(err(format!("`{what}` must not be zero")))
            }
        };
        // The ascent direction of a slope or tilted height field, horizontal.
        let direction = || {
            let d = g.direction.map_or(Vec3::x(), |d| d.0);
            unit(Vec3::new(d.x, d.y, 0.0), "direction (horizontal part)")
        };
        let (shape, local) = match g.kind {
            GroundKind::Plane => {
                let n = unit(g.normal.map_or(Vec3::z(), |n| n.0), "normal")?;
                let offset = g.offset.map_or(0.0, |x| x.0);
                (Shape::HalfSpace { normal: n }, Transform::from_translation(n * offset))
            }
            GroundKind::Slope => {
                let angle = g.angle_deg.ok_or_else(|| err("a slope needs `angle_deg`".to_string()))?.0;
                if angle.abs() >= 90.0 {
                    return Err(err(format!("`angle_deg` must be between -90 and 90, got {angle}")));
                }
                let a = angle.to_radians();
                let n = -a.sin() * direction()? + a.cos() * Vec3::z();
                (Shape::HalfSpace { normal: n }, Transform::identity())
            }
            GroundKind::Heightfield => {
                let [sx, sy] =
                    g.size.ok_or_else(|| err("a heightfield needs `size = [x, y]`".to_string()))?;
                let (sx, sy) = (sx.0, sy.0);
                let tilt = g.angle_deg.map_or(0.0, |x| x.0);
                if tilt.abs() >= 90.0 {
                    return Err(err(format!("`angle_deg` must be between -90 and 90, got {tilt}")));
                }
                let slope = tilt.to_radians().tan() * direction()?;
                let heights = if let Some(rows) = &g.heights {
                    if let Some((key, _)) = given[6..].iter().find(|(_, set)| *set) {
                        return Err(err(format!(
                            "`{key}` generates heights: give it or `heights`, not both"
                        )));
                    }
                    let nx = rows.len();
                    let ny = rows.first().map_or(0, Vec::len);
                    if nx < 2 || ny < 2 || rows.iter().any(|r| r.len() != ny) {
                        return Err(err(
                            "`heights` must be at least 2 rows of at least 2 values, all rows of the same length"
                                .to_string(),
                        ));
                    }
                    DMatrix::from_fn(nx, ny, |i, j| rows[i][j].0)
                } else {
                    let [nx, ny] = g.samples.map_or([33, 33], |s| [s[0].0, s[1].0]);
                    if nx < 2 || ny < 2 {
                        return Err(err("`samples` must be at least [2, 2]".to_string()));
                    }
                    if nx.checked_mul(ny).is_none_or(|n| n > MAX_HEIGHTFIELD_SAMPLES) {
                        return Err(err(format!(
                            "`samples` = [{nx}, {ny}] is more than {MAX_HEIGHTFIELD_SAMPLES} heights"
                        )));
                    }
                    let amplitude = g.bump_height.map_or(0.0, |x| x.0);
                    let k = 2.0 * std::f64::consts::PI / g.bump_wavelength.map_or(1.0, |x| x.0);
                    DMatrix::from_fn(nx, ny, |i, j| {
                        let x = -sx / 2.0 + sx * i as f64 / (nx - 1) as f64;
                        let y = -sy / 2.0 + sy * j as f64 / (ny - 1) as f64;
                        amplitude * (k * x).sin() * (k * y).sin()
                    })
                };
                let (nx, ny) = heights.shape();
                let heights = DMatrix::from_fn(nx, ny, |i, j| {
                    let x = -sx / 2.0 + sx * i as f64 / (nx - 1) as f64;
                    let y = -sy / 2.0 + sy * j as f64 / (ny - 1) as f64;
                    heights[(i, j)] + slope.x * x + slope.y * y
                });
                // Beyond this, collision queries on the field lose all precision (and fail).
                let max = crate::model::ranges::MAX_LENGTH;
                if sx.max(sy) > max || heights.iter().any(|h| h.is_nan() || h.abs() > max) {
                    return Err(err(format!(
                        "the height field's size and heights must be at most {max:e} m"
                    )));
                }
                (Shape::HeightField { heights, size_x: sx, size_y: sy }, Transform::identity())
            }
        };
        world.add_static(&name, &shape, frame * local, material).map_err(self.world_error(span.clone()))?;
        Ok(())
    }
}
