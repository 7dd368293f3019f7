//! Typed errors, one enum per area. Messages name the body, joint, file or quantity concerned.

use thiserror::Error;

/// An invalid model description, found by [`crate::model::ModelBuilder::build`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ModelError {
    /// Mass negative, NaN or infinite.
    #[error("body `{body}`: mass {} is negative or not finite", crate::model::ranges::Num(*.mass))]
    InvalidMass {
        /// Body name.
        body: String,
        /// The offending mass (kg).
        mass: f64,
    },
    /// A mass, inertia or length beyond the range gelenk computes with ([`crate::model::ranges`]).
    #[error("{} `{name}`: {} {} {unit} is beyond {} {unit}, the largest gelenk accepts",
        .quantity.owner(), .quantity.name(), crate::model::ranges::Num(*.value),
        crate::model::ranges::Num(.quantity.limit()), unit = .quantity.unit())]
    OutOfRange {
        /// The body's name (the joint's for a placement offset).
        name: String,
        /// The quantity.
        quantity: crate::model::ranges::Quantity,
        /// The value given (its magnitude for a vector).
        value: f64,
    },
    /// Centre of mass or inertia tensor contains NaN or infinity.
    #[error("body `{body}`: centre of mass or inertia tensor is not finite")]
    NonFiniteInertia {
        /// Body name.
        body: String,
    },
    /// Rotational inertia not symmetric.
    #[error("body `{body}`: inertia tensor is not symmetric")]
    InertiaNotSymmetric {
        /// Body name.
        body: String,
    },
    /// Rotational inertia has a negative principal moment.
    #[error(
        "body `{body}`: inertia tensor is not positive semi-definite (principal moments {moments:?} kg·m²)"
    )]
    InertiaNotPositive {
        /// Body name.
        body: String,
        /// Principal moments, ascending (kg·m²).
        moments: [f64; 3],
    },
    /// Principal moments violate `I₁ + I₂ ≥ I₃`: no mass distribution has this inertia.
    #[error(
        "body `{body}`: principal moments {moments:?} kg·m² violate the triangle inequality I1 + I2 >= I3"
    )]
    InertiaTriangleInequality {
        /// Body name.
        body: String,
        /// Principal moments, ascending (kg·m²).
        moments: [f64; 3],
    },
    /// A joint axis is zero, NaN or infinite.
    #[error("joint `{joint}`: axis {axis:?} is zero or not finite")]
    InvalidAxis {
        /// Joint name.
        joint: String,
        /// The axis as given.
        axis: [f64; 3],
    },
    /// The two axes of a universal or hinge2 joint are parallel: one degree of freedom is lost.
    #[error("joint `{joint}`: its two axes are parallel")]
    ParallelAxes {
        /// Joint name.
        joint: String,
    },
    /// A body names a parent that does not exist.
    #[error("body `{body}`: unknown parent `{parent}`")]
    UnknownParent {
        /// Body name.
        body: String,
        /// The missing parent's name.
        parent: String,
    },
    /// Two bodies, or two joints, share a name (or a body is called `universe`).
    #[error("duplicate {what} name `{name}`")]
    DuplicateName {
        /// "body" or "joint".
        what: &'static str,
        /// The repeated name.
        name: String,
    },
    /// The parent relation has a cycle, so the bodies are not a tree.
    #[error("body `{body}` lies on a cycle of parents; a kinematic tree has none")]
    Cycle {
        /// A body on the cycle.
        body: String,
    },
    /// A placement contains NaN or infinity.
    #[error("joint `{joint}`: placement is not finite")]
    NonFinitePlacement {
        /// Joint name.
        joint: String,
    },
    /// Limits of the wrong length, NaN, or lower above upper.
    #[error("joint `{joint}`: invalid limits: {reason}")]
    InvalidLimits {
        /// Joint name.
        joint: String,
        /// What is wrong.
        reason: String,
    },
    /// Suspension stiffness or damping negative or not finite.
    #[error("joint `{joint}`: suspension stiffness and damping must be finite and non-negative")]
    InvalidSuspension {
        /// Joint name.
        joint: String,
    },
}

/// An algorithm refused its input or met a singular problem. The output buffers are then
/// unspecified, but never silently returned as a result.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DynamicsError {
    /// An input vector has the wrong length.
    #[error("{what} has length {got}, the model needs {expected}")]
    DimensionMismatch {
        /// Which input ("q", "v", "a", "tau").
        what: &'static str,
        /// Length the model needs.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// An input holds NaN or infinity.
    #[error("{what}[{index}] (joint `{joint}`) is not finite")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// Index into it.
        index: usize,
        /// Joint owning that index.
        joint: String,
    },
    /// A result came out NaN or infinite although the inputs were finite: the model's masses,
    /// lengths or the state are too large for double precision (an overflow).
    #[error("{what} of {at} is not finite (overflow: the model's masses, inertias, lengths or the state are too large)")]
    NonFiniteResult {
        /// Which result ("rnea", "aba", "mass matrix", "kinetic energy", …).
        what: &'static str,
        /// Where: "joint `name`" for a joint's entry, "the model" for a scalar.
        at: String,
    },
    /// A ball or free joint's quaternion is (nearly) zero: no rotation to normalize it to.
    #[error("joint `{joint}`: its quaternion has norm {norm:e}, too small to be normalized into a rotation")]
    DegenerateQuaternion {
        /// Joint name.
        joint: String,
        /// Euclidean norm of the four coordinates.
        norm: f64,
    },
    /// The mass matrix is singular: the subtree below this joint has no mass or inertia to move.
    #[error("joint `{joint}`: the subtree it moves has no mass or inertia along its motion, so the mass matrix is singular")]
    SingularMassMatrix {
        /// Joint name.
        joint: String,
    },
    /// A body or frame index out of range.
    #[error("index {index} is out of range ({count} {what})")]
    IndexOutOfRange {
        /// "bodies" or "frames".
        what: &'static str,
        /// Index given.
        index: usize,
        /// Number available.
        count: usize,
    },
}

/// An error while turning geometry into colliders or while detecting collisions. Every variant
/// names the link (or collider) it concerns.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CollisionError {
    /// A mesh URI resolved to no existing file.
    #[error("link `{link}`: mesh `{uri}` not found (looked for: {tried})")]
    MeshNotFound {
        /// Link declaring the mesh.
        link: String,
        /// URI as written in the model.
        uri: String,
        /// The candidate paths tried, separated by ", ".
        tried: String,
    },
    /// A mesh file exists but could not be read or parsed.
    #[error("link `{link}`: mesh `{path}` could not be read: {message}")]
    MeshUnreadable {
        /// Link declaring the mesh.
        link: String,
        /// Resolved file path.
        path: String,
        /// The loader's message.
        message: String,
    },
    /// A shape has invalid parameters (non-positive size, non-finite numbers, too few points, a
    /// degenerate convex hull, a half-space on a moving body, ...).
    #[error("link `{link}`: invalid collision shape: {what}")]
    InvalidShape {
        /// Link (or collider name) owning the shape.
        link: String,
        /// What is wrong.
        what: String,
    },
    /// A multibody, body or collider index out of range.
    #[error("index {index} is out of range ({count} {what})")]
    IndexOutOfRange {
        /// "multibodies", "bodies" or "colliders".
        what: &'static str,
        /// Index given.
        index: usize,
        /// Number available.
        count: usize,
    },
    /// The pose of a body holding colliders is not finite.
    #[error("collider `{collider}`: its body pose is not finite")]
    NonFinitePose {
        /// Name of the collider (its link).
        collider: String,
    },
    /// `Data` given for a multibody does not belong to a model of the same size.
    #[error("multibody {multibody}: data has {got} bodies, the model had {expected}")]
    DataMismatch {
        /// Multibody index.
        multibody: usize,
        /// Bodies in the model when it was added.
        expected: usize,
        /// Bodies in the data given.
        got: usize,
    },
}

/// An MJCF (MuJoCo XML) document that cannot become a scene, from [`crate::io::mjcf`]. Every
/// variant names the file (`<string>` for text); all but [`MjcfError::Io`] and
/// [`MjcfError::Xml`] (raised before any element exists) also name the element concerned, as
/// `<tag name="…"> at line N`.
#[derive(Debug, Error)]
pub enum MjcfError {
    /// The file could not be read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File path.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not well-formed XML; the parser's message gives the position.
    #[error("{file}: not well-formed XML: {message}")]
    Xml {
        /// File path.
        file: String,
        /// The XML parser's message, with line and column.
        message: String,
    },
    /// An attribute value that is not usable: not a number, the wrong count of numbers, out of
    /// range (such as a negative size), or an unknown keyword (such as an unknown geom type).
    #[error("{file}: {element}: attribute {attribute}=\"{value}\": {what}")]
    InvalidAttribute {
        /// File path.
        file: String,
        /// The element, as `<tag name="…"> at line N`.
        element: String,
        /// Attribute name.
        attribute: String,
        /// The value as written (possibly inherited from a `<default>` class).
        value: String,
        /// What is wrong.
        what: String,
    },
    /// A required attribute is absent (and not given by a `<default>` class either).
    #[error("{file}: {element}: attribute `{attribute}` is required")]
    MissingAttribute {
        /// File path.
        file: String,
        /// The element, as `<tag name="…"> at line N`.
        element: String,
        /// Attribute name.
        attribute: String,
    },
    /// A valid MJCF feature that changes the dynamics or the contacts but that gelenk cannot
    /// represent (mesh geoms, tendons, equality constraints, joint springs, mocap bodies, …).
    #[error("{file}: {element}: not supported by gelenk: {what}")]
    Unsupported {
        /// File path.
        file: String,
        /// The element, as `<tag name="…"> at line N`.
        element: String,
        /// What is not supported.
        what: String,
    },
    /// A structural error: wrong root element, unknown default class, a free joint below a
    /// moving body, a plane on a moving body, ….
    #[error("{file}: {element}: {what}")]
    Invalid {
        /// File path.
        file: String,
        /// The element, as `<tag name="…"> at line N`.
        element: String,
        /// What is wrong.
        what: String,
    },
    /// The scene is well-formed but the model builder rejected it (duplicate names, invalid
    /// inertia, …).
    #[error("{file}: {element}: {source}")]
    Model {
        /// File path.
        file: String,
        /// The body or joint element the model error is about (`<worldbody>` if unknown).
        element: String,
        /// The model error.
        source: ModelError,
    },
}

/// Why a solver returned no solution.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SolverError {
    /// The problem's sizes or numbers are inconsistent.
    #[error("invalid problem: {0}")]
    InvalidProblem(String),
    /// Lemke's method left along a secondary ray on every path it tried: no solution is
    /// reachable from its covering vectors; the certificate of the last ray says how well the
    /// ray checks against M and q and whether it proves the LCP infeasible.
    #[error("Lemke: ray termination after {pivots} pivots (no solution reachable): {certificate}")]
    LemkeRay {
        /// Pivots done (over all paths).
        pivots: usize,
        /// The last path's ray, checked.
        certificate: Box<crate::solvers::RayCertificate>,
    },
    /// Lemke's method came back to a basis it had left: rounding defeated its anti-cycling rule.
    #[error("Lemke: the path cycled after {pivots} pivots (a basis came back)")]
    LemkeCycle {
        /// Pivots done (over all paths).
        pivots: usize,
    },
    /// Lemke's method used up its work budget ([`crate::solvers::LemkeOptions::max_operations`],
    /// or the share of its later paths, [`crate::solvers::LemkeOptions::fallback_share`])
    /// without an answer: on large degenerate LCPs (thousands of variables
    /// with a dense basis) each pivot costs O(k²) and a refactorization O(k³).
    #[error("Lemke: work budget of {budget:.1e} operations used up after {pivots} pivots (LemkeOptions::max_operations and fallback_share)")]
    LemkeWorkLimit {
        /// Pivots done (over all paths).
        pivots: usize,
        /// The budget (floating-point operations, estimated from the basis's sizes).
        budget: f64,
    },
    /// The LCP's matrix would store more entries than
    /// [`crate::solvers::LemkeOptions::max_matrix_entries`] allows (a problem whose contacts
    /// all share bodies makes M nearly dense: memory grows with the square of its size).
    #[error(
        "Lemke: the LCP's matrix would store more than {limit} entries (LemkeOptions::max_matrix_entries)"
    )]
    LemkeMatrixTooLarge {
        /// The limit (stored entries).
        limit: usize,
    },
    /// Lemke's method met a basis whose LU is singular to working precision.
    #[error("Lemke: singular basis after {pivots} pivots (smallest/largest LU pivot {ratio:.1e})")]
    LemkeSingularBasis {
        /// Pivots done (over all paths).
        pivots: usize,
        /// min |U_ii| / max |U_ii| of the failed factorization.
        ratio: f64,
    },
    /// Lemke's method ran out of pivots.
    #[error("Lemke: pivot limit {pivots} reached")]
    PivotLimit {
        /// The limit.
        pivots: usize,
    },
    /// The impulses came out NaN or infinite (a degenerate problem, e.g. a subnormal diagonal).
    #[error("{solver}: the impulses came out NaN or infinite (a degenerate problem)")]
    NonFinite {
        /// Solver name.
        solver: &'static str,
    },
    /// A solution was found but its residual is above the tolerance.
    #[error("{solver}: residual {residual:.3e} above tolerance {tolerance:.1e}")]
    Inaccurate {
        /// Solver name.
        solver: String,
        /// Residual reached (m/s).
        residual: f64,
        /// Tolerance asked (m/s).
        tolerance: f64,
    },
    /// clarabel stopped without a solution.
    #[error("clarabel: {status}")]
    Clarabel {
        /// clarabel's status.
        status: String,
    },
    /// Every solver of a chain failed; the reasons in order.
    #[error("every solver failed: {0}")]
    AllFailed(String),
}
