//! From a checked document to a [`Scene`]: world options, materials and pairs, then the grounds,
//! URDF models, primitive bodies and vehicles in file order, then what is recorded. Grounds are
//! built in [`ground`], models and bodies (and their copies) in [`bodies`].

mod bodies;
mod ground;

use super::schema::{Document, DrivenName, VehicleSection};
use super::source::Source;
use super::values::{Count, Finite, MaterialRef, NonNegative, V3};
use super::{
    Location, RecordOptions, Scene, SceneError, ScriptedVehicle, SetUpProgress, TimedCommand, INTEGRATORS,
};
use crate::constraints::{ContactParameters, JointLimitParameters};
use crate::io::limits::ReadLimits;
use crate::math::{Transform, Vec3};
use crate::vehicle::{Driven, Vehicle, VehicleConfig};
use crate::world::{SolverKind, StepError, World, WorldOptions};
use std::collections::{HashMap, HashSet};
use std::ops::Range;
use toml::Spanned;

/// Run-time replacements of scene values.
#[derive(Clone, Debug, Default)]
pub(super) struct Overrides {
    /// Time step (s) instead of `[world] dt`.
    pub(super) dt: Option<f64>,
    /// Solver chain instead of `[world] solver`.
    pub(super) solvers: Option<Vec<SolverKind>>,
}

/// Checks the scene's text and builds its world.
pub(super) fn build(
    source: Source,
    overrides: &Overrides,
    progress: &mut dyn FnMut(SetUpProgress),
) -> Result<Scene, SceneError> {
    if source.text.trim_start().starts_with('<') {
        let message =
            "this is XML (a URDF or MJCF file?), not a scene: scene files are TOML (see models/*.toml)";
        return Err(source.invalid(0..0, message.to_string()));
    }
    let limits = ReadLimits::default();
    let whole = |message: String| SceneError::Invalid {
        at: Location { file: source.file.clone(), line: 0, column: 0, key: String::new() },
        message,
    };
    limits.check_len(&source.text).map_err(whole)?;
    limits.check_data_depth(&source.text).map_err(whole)?;
    let doc: Document = toml::from_str(&source.text).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        let message = e.message().trim_end().to_string();
        if e.span().is_some() {
            source.invalid(span, message)
        } else {
            SceneError::Invalid {
                at: Location { file: source.file.clone(), line: 0, column: 0, key: String::new() },
                message,
            }
        }
    })?;
    if doc.ground.is_empty() && doc.urdf.is_empty() && doc.body.is_empty() {
        return Err(whole(
            "the scene is empty: it has no [[ground]], [[body]] or [[urdf]] (see models/*.toml)".to_string(),
        ));
    }
    let total = doc.urdf.iter().map(|u| copies_of(u.get_ref().count)).sum::<usize>()
        + doc.body.iter().map(|b| copies_of(b.get_ref().count)).sum::<usize>();
    let mut b = Builder {
        src: &source,
        materials: HashMap::new(),
        names: HashSet::new(),
        progress: SetUpProgress { built: 0, total },
        report: progress,
        bodies: 0,
    };

    // World options.
    let w = &doc.world;
    let defaults = WorldOptions::default();
    let mut options = WorldOptions {
        dt: w.dt.map_or(defaults.dt, |x| x.0),
        gravity: w.gravity.map_or(defaults.gravity, |g| g.0),
        friction: w.friction.map_or(defaults.friction, |f| f.0),
        solvers: w.solver.clone().map_or(defaults.solvers.clone(), |s| s.0),
        tolerance: w.tolerance.map_or(defaults.tolerance, |x| x.0),
        softness: w.softness.map_or(defaults.softness, |x| x.0),
        softness_damping: w.softness_damping.map_or(defaults.softness_damping, |x| x.0),
        accept_last: w.accept_last.unwrap_or(defaults.accept_last),
        lemke_operations: w.lemke_operations.map_or(defaults.lemke_operations, |x| x.0),
        lemke_matrix_entries: w.lemke_matrix_entries.unwrap_or(defaults.lemke_matrix_entries),
        contact: doc.contact.apply(ContactParameters::default()),
        ..defaults
    };
    options.collision.margin = w.margin.map_or(options.collision.margin, |x| x.0);
    options.speculation.always_within =
        w.speculative_within.map_or(options.speculation.always_within, |x| x.0);
    options.speculation.speed_factor = w.speculative_factor.map_or(options.speculation.speed_factor, |x| x.0);
    options.collision.collide_joined_bodies =
        w.collide_joined_bodies.unwrap_or(options.collision.collide_joined_bodies);
    options.continuous_collision = w.continuous_collision.unwrap_or(options.continuous_collision);
    options.contact_projection.enabled = w.contact_projection.unwrap_or(options.contact_projection.enabled);
    options.collision.reuse = w.contact_reuse.map_or(options.collision.reuse, |r| r.0);
    options.mass_matrix_reuse = w.mass_matrix_reuse.map_or(options.mass_matrix_reuse, |r| r.0);
    options.sleep.enabled = w.sleep.unwrap_or(options.sleep.enabled);
    if let Some(name) = &w.integrator {
        options.integrator = crate::world::parse_integrator(&name.0).unwrap_or(options.integrator);
    }
    let l = &doc.limits;
    let lim = JointLimitParameters::default();
    options.limits = JointLimitParameters {
        erp: l.erp.map_or(lim.erp, |x| x.0),
        cfm: l.cfm.map_or(lim.cfm, |x| x.0),
        restitution: l.restitution.map_or(lim.restitution, |x| x.0),
        bounce_velocity: l.bounce_velocity.map_or(lim.bounce_velocity, |x| x.0),
        margin: l.margin.map_or(lim.margin, |x| x.0),
        speculative_within: l.speculative_within.map_or(lim.speculative_within, |x| x.0),
    };
    if let Some(dt) = overrides.dt {
        options.dt = dt;
    }
    if let Some(solvers) = &overrides.solvers {
        options.solvers = solvers.clone();
    }
    let (dt_min, dt_max) = crate::model::ranges::TIME_STEP_RANGE;
    if !(dt_min..=dt_max).contains(&options.dt) {
        return Err(whole(format!(
            "[world] dt = {} s is outside [{dt_min:e}, {dt_max}] s, the time steps gelenk accepts",
            crate::model::ranges::Num(options.dt)
        )));
    }
    let mut world = World::new(options.clone());
    if let Some(threads) = &w.threads {
        world.set_threads(threads.get_ref().0).map_err(|e| b.src.invalid(threads.span(), e.to_string()))?;
    }

    // Materials and pairs.
    for m in &doc.material {
        let span = m.span();
        let m = m.get_ref();
        if m.index == 0 {
            return Err(b.src.invalid(span, "material 0 is the default material: set it in [contact]"));
        }
        if b.materials.values().any(|&i| i == m.index) {
            return Err(b.src.invalid(span, format!("material {} is defined twice", m.index)));
        }
        let name = m.name.clone().unwrap_or_else(|| format!("#{}", m.index));
        if b.materials.insert(name.clone(), m.index).is_some() {
            return Err(b.src.invalid(span, format!("two materials are named `{name}`")));
        }
        world.set_material(m.index, m.apply(options.contact));
    }
    for p in &doc.pair {
        let span = p.span();
        let p = p.get_ref();
        let a = b.material(&p.materials[0], span.clone())?;
        let c = b.material(&p.materials[1], span)?;
        world.set_pair_parameters(a, c, p.apply(options.contact));
    }

    for (i, g) in doc.ground.iter().enumerate() {
        b.ground(&mut world, i, g)?;
    }
    let mut warnings = Vec::new();
    for u in &doc.urdf {
        warnings.extend(b.urdf(&mut world, u)?);
    }
    warnings.extend(world.collision().warnings().iter().cloned());
    for (i, body) in doc.body.iter().enumerate() {
        b.body(&mut world, i, body)?;
    }
    let mut vehicles = Vec::new();
    for v in &doc.vehicle {
        vehicles.push(b.vehicle(&mut world, v)?);
    }

    // Recording.
    let mut record = RecordOptions::default();
    let mut recorded: Vec<usize> = (0..world.multibody_count()).collect();
    if let Some(r) = &doc.record {
        let section = r.get_ref();
        record.every = section.every.map_or(record.every, |x| x.0);
        record.velocities = section.velocities;
        record.energy = section.energy;
        if let Some(names) = &section.multibodies {
            recorded.clear();
            for name in names {
                let index = (0..world.multibody_count())
                    .find(|&i| world.multibody_name(i) == name.get_ref())
                    .ok_or_else(|| {
                        b.src.invalid(name.span(), format!("no multibody `{}`", name.get_ref()))
                    })?;
                recorded.push(index);
            }
        }
    }

    Ok(Scene {
        name: doc.name.clone().unwrap_or_else(|| source.stem.clone()),
        description: doc.description.clone().unwrap_or_default(),
        file: source.path.clone(),
        world,
        duration: doc.world.duration.map_or(1.0, |x| x.0),
        integrator: doc.world.integrator.clone().map_or(INTEGRATORS[0].to_string(), |x| x.0),
        recorded,
        record,
        warnings,
        vehicles,
        source,
    })
}

/// State shared while building one scene: the source for errors, materials by name, and the
/// multibody names taken so far.
struct Builder<'a> {
    src: &'a Source,
    materials: HashMap<String, u32>,
    names: HashSet<String>,
    /// The bodies and models built so far, of all the scene has.
    progress: SetUpProgress,
    /// Told after each one.
    report: &'a mut dyn FnMut(SetUpProgress),
    /// Moving bodies the entries so far create (at most [`MAX_SCENE_BODIES`]).
    bodies: usize,
}

/// Most moving bodies a scene creates, over all entries and their copies: 100 000 boxes fit,
/// and so do 10 000 ragdolls of 16 bodies; a scene beyond this would spend minutes and
/// gigabytes in its set-up before the first step.
const MAX_SCENE_BODIES: usize = 200_000;

/// How many copies `count` makes (1 without it).
fn copies_of(count: Option<Count>) -> usize {
    match count {
        None => 1,
        Some(Count::Row(n)) => n,
        Some(Count::Grid([x, y, z])) => x * y * z,
    }
}

impl<'a> Builder<'a> {
    /// Counts one more body or model built and reports it.
    fn built_one(&mut self) {
        self.progress.built += 1;
        (self.report)(self.progress);
    }

    fn material(&self, m: &MaterialRef, span: Range<usize>) -> Result<u32, SceneError> {
        match m {
            MaterialRef::Index(0) => Ok(0),
            MaterialRef::Index(i) if self.materials.values().any(|k| k == i) => Ok(*i),
            MaterialRef::Index(i) => {
                Err(self.src.invalid(span, format!("no material {i} (define it in [[material]])")))
            }
            MaterialRef::Name(name) => self.materials.get(name).copied().ok_or_else(|| {
                self.src.invalid(span, format!("no material named `{name}` (define it in [[material]])"))
            }),
        }
    }

    fn material_of(&self, m: &Option<Spanned<MaterialRef>>) -> Result<u32, SceneError> {
        m.as_ref().map_or(Ok(0), |m| self.material(m.get_ref(), m.span()))
    }

    /// Counts `n` more moving bodies against [`MAX_SCENE_BODIES`].
    fn claim_bodies(&mut self, n: usize, span: Range<usize>) -> Result<(), SceneError> {
        match self.bodies.checked_add(n).filter(|&total| total <= MAX_SCENE_BODIES) {
            Some(total) => {
                self.bodies = total;
                Ok(())
            }
            None => Err(self.src.invalid(
                span,
                format!(
                    "the scene would hold {} moving bodies; at most {MAX_SCENE_BODIES} (fewer copies, or a smaller `count`)",
                    self.bodies.saturating_add(n)
                ),
            )),
        }
    }

    fn claim_name(&mut self, name: &str, span: Range<usize>) -> Result<(), SceneError> {
        if self.names.insert(name.to_string()) {
            Ok(())
        } else {
            Err(self
                .src
                .invalid(span, format!("two multibodies are named `{name}`: give each entry its own `name`")))
        }
    }

    fn world_error(&self, span: Range<usize>) -> impl Fn(StepError) -> SceneError + 'a {
        let src = self.src;
        move |source| SceneError::World { at: src.location(span.clone()), source: Box::new(source) }
    }

    fn vehicle(&self, world: &mut World, v: &Spanned<VehicleSection>) -> Result<ScriptedVehicle, SceneError> {
        let span = v.span();
        let v = v.get_ref();
        let name = v.multibody.get_ref();
        let index = (0..world.multibody_count())
            .find(|&i| world.multibody_name(i) == name)
            .ok_or_else(|| self.src.invalid(v.multibody.span(), format!("no multibody `{name}`")))?;
        let defaults = VehicleConfig::buggy();
        let config = VehicleConfig {
            front: v.front.clone().unwrap_or(defaults.front),
            rear: v.rear.clone().unwrap_or(defaults.rear),
            driven: match v.driven {
                None => defaults.driven,
                Some(DrivenName::Rear) => Driven::Rear,
                Some(DrivenName::Front) => Driven::Front,
                Some(DrivenName::All) => Driven::All,
            },
            wheel_radius: v.wheel_radius.map_or(defaults.wheel_radius, |x| x.0),
            drive_torque: v.drive_torque.map_or(defaults.drive_torque, |x| x.0),
            brake_torque: v.brake_torque.map_or(defaults.brake_torque, |x| x.0),
            steering_gain: v.steering_gain.map_or(defaults.steering_gain, |x| x.0),
            steering_rate: v.steering_rate.map_or(defaults.steering_rate, |x| x.0),
            steering_torque: v.steering_torque.map_or(defaults.steering_torque, |x| x.0),
            patch_contact: v.patch_contact.unwrap_or(defaults.patch_contact),
        };
        let vehicle = Vehicle::attach(world, index, config)
            .map_err(|e| self.src.invalid(span.clone(), e.to_string()))?;
        let mut commands = Vec::with_capacity(v.command.len());
        for c in &v.command {
            let cspan = c.span();
            let c = c.get_ref();
            if c.speed.is_none() && c.coast.is_none() && c.steering_deg.is_none() && c.brake.is_none() {
                return Err(self.src.invalid(
                    cspan,
                    "a command sets at least one of `speed`, `coast`, `steering_deg`, `brake`",
                ));
            }
            if c.speed.is_some() && c.coast == Some(true) {
                return Err(self.src.invalid(cspan, "give `speed` or `coast = true`, not both"));
            }
            if let Some(deg) = c.steering_deg {
                if deg.0.abs() >= 90.0 {
                    return Err(self.src.invalid(
                        cspan,
                        format!("`steering_deg` must be between -90 and 90, got {}", deg.0),
                    ));
                }
            }
            commands.push(TimedCommand {
                at: c.at.0,
                speed: c.speed.map(|x| x.0),
                coast: c.coast.unwrap_or(false),
                steering: c.steering_deg.map(|x| x.0.to_radians()),
                brake: c.brake,
            });
        }
        // Stable: commands given for the same time apply in the order written.
        commands.sort_by(|a, b| a.at.total_cmp(&b.at));
        Ok(ScriptedVehicle { vehicle, commands, applied: 0 })
    }
}

/// Where the copies of a `[[body]]` or `[[urdf]]` entry go: `count = n` copies in a row at
/// `k·spacing`, or `count = [nx, ny, nz]` in a grid at `(i·sx, j·sy, k·sz)`, each moved by up to
/// `jitter` m per axis (drawn by the caller, whose random sequence this leaves alone).
pub(super) struct Copies {
    /// Copies along x, y, z (a row: `[n, 1, 1]`).
    dims: [usize; 3],
    /// `count` was a grid.
    grid: bool,
    /// `spacing` (m): between neighbours in a row, per axis in a grid.
    spacing: Vec3,
    /// `jitter` (m).
    pub(super) jitter: f64,
}

impl Copies {
    /// The copies an entry asks for; an error message when several lack a `spacing` or would lie
    /// on each other.
    pub(super) fn new(
        count: Option<Count>,
        spacing: Option<V3>,
        jitter: Option<NonNegative>,
    ) -> Result<Self, String> {
        let (dims, grid) = match count {
            None => ([1, 1, 1], false),
            Some(Count::Row(n)) => ([n, 1, 1], false),
            Some(Count::Grid(d)) => (d, true),
        };
        let total = dims[0] * dims[1] * dims[2];
        let spacing = match (spacing, total) {
            (Some(s), _) => s.0,
            (None, 1) => Vec3::zeros(),
            (None, _) => return Err(format!("{total} copies need `spacing`")),
        };
        let jitter = jitter.map_or(0.0, |x| x.0);
        let max = crate::model::ranges::MAX_LENGTH;
        if jitter > max || spacing.amax() > max {
            return Err(format!("`spacing` and `jitter` must be at most {max:e} m"));
        }
        if copies_coincide(dims, grid, &spacing, jitter) {
            return Err(format!(
                "{total} copies with `spacing` {:?} and no `jitter` would lie on each other",
                spacing.as_slice()
            ));
        }
        Ok(Self { dims, grid, spacing, jitter })
    }

    /// The number of copies.
    pub(super) fn len(&self) -> usize {
        self.dims.iter().product()
    }

    /// The copies' grid cells `(i, j, k)`, i fastest (a row is `(i, 0, 0)`).
    pub(super) fn cells(&self) -> impl Iterator<Item = [usize; 3]> {
        let [nx, ny, nz] = self.dims;
        (0..nz).flat_map(move |k| (0..ny).flat_map(move |j| (0..nx).map(move |i| [i, j, k])))
    }

    /// The name of the copy in `cell`: `base` for a single copy, `{base}{i}` in a row,
    /// `{base}_{i}_{j}_{k}` in a grid.
    pub(super) fn name(&self, base: &str, [i, j, k]: [usize; 3]) -> String {
        if self.dims == [1, 1, 1] {
            base.to_string()
        } else if self.grid {
            format!("{base}_{i}_{j}_{k}")
        } else {
            format!("{base}{i}")
        }
    }

    /// The offset (m) of the copy in `cell` from the entry's position, before jitter.
    pub(super) fn offset(&self, [i, j, k]: [usize; 3]) -> Vec3 {
        let s = &self.spacing;
        if self.grid {
            Vec3::new(i as f64 * s.x, j as f64 * s.y, k as f64 * s.z)
        } else {
            i as f64 * s
        }
    }
}

/// Whether copies placed by `count` (`dims`, a grid or a row) at `spacing` land on each other:
/// a row of several with no spacing, or a grid of several along an axis without spacing along
/// it, and no jitter to move them apart (identical bodies on each other have no contact normal).
fn copies_coincide(dims: [usize; 3], grid: bool, spacing: &Vec3, jitter: f64) -> bool {
    if jitter > 0.0 {
        return false;
    }
    if grid {
        (0..3).any(|a| dims[a] > 1 && spacing[a] == 0.0)
    } else {
        dims[0] > 1 && *spacing == Vec3::zeros()
    }
}

/// A pose from `position` and either `rpy` (rad) or `quaternion` (`[x, y, z, w]`).
fn pose(position: Option<V3>, rpy: Option<V3>, quaternion: Option<[Finite; 4]>) -> Result<Transform, String> {
    let p = position.map_or(Vec3::zeros(), |p| p.0);
    match (rpy, quaternion) {
        (Some(_), Some(_)) => Err("give `rpy` or `quaternion`, not both".to_string()),
        (None, Some(q)) => {
            let xyzw = q.map(|x| x.0);
            if xyzw.iter().map(|x| x * x).sum::<f64>().sqrt() < 1e-9 {
                return Err("`quaternion` must not be zero".to_string());
            }
            Ok(Transform::from_translation_quaternion(p, xyzw))
        }
        (r, None) => {
            let r = r.map_or(Vec3::zeros(), |r| r.0);
            Ok(Transform::from_xyz_rpy([p.x, p.y, p.z], [r.x, r.y, r.z]))
        }
    }
}
