//! URDF models, read with roxmltree as ROS's urdfdom reads them, with gelenk's extension for
//! universal, hinge2 and ball-limited joints. The page `docs/urdf.md` says the same for users.
//!
//! Mapping: `revolute`/`continuous` → hinge, `prismatic` → slider, `fixed` → fused into the
//! parent, `floating` → free, `planar` → planar (the URDF axis is the plane normal), `spherical`
//! → ball. Axes are normalized. The inertial origin's rotation is applied to the inertia tensor.
//! Joints are numbered depth-first, siblings in the order the file lists them (Pinocchio orders
//! siblings by joint name: `docs/conventions.md`). Position
//! limits of `continuous` joints are ignored; a `<limit>` of zero velocity or zero effort, and a
//! zero-width position range, mean "not given". Collision and visual shapes are kept in the model
//! ([`crate::model::GeometrySpec`]); no mesh file is opened unless
//! [`UrdfOptions::inertia_from_collision`] asks for the inertias of the collision shapes.
//! `<mimic>` is not modelled: the joint moves on its own.
//!
//! ## Lenient by default, strict on request
//! Files from the wild carry vendors' and tools' extensions (`<joint_properties>`, `<self_filter>`,
//! `<kinematic>`, `rpy` on `<axis>`), repeated elements, missing values and inertias no rigid body
//! can have. By default each of these loads as urdfdom (ROS, Pinocchio) loads it, and is a
//! [`UrdfWarning`] naming the element and its line ([`load_file_with_warnings`]): an unknown element
//! or attribute is read past, the first of a repeated element counts, a missing required value
//! takes URDF's default, inverted limits mean no limit (Bullet's convention), whitespace before the
//! XML declaration and NUL bytes after the root are removed, and an inconsistent inertia (a
//! negative principal moment, or moments violating the triangle inequality I₁ + I₂ ≥ I₃) is kept
//! as written (so that the dynamics agree with Pinocchio's) or, with
//! [`UrdfOptions::balance_inertia`], replaced as MuJoCo's `balanceinertia` does. A singular
//! inertia of a link with mass (a point, a rod: PyBullet's random objects write diag(1, 1, 0)) is
//! kept with a warning that names [`UrdfOptions::inertia_from_collision`], PyBullet's default.
//! [`UrdfOptions::strict`] makes every warning an error ([`UrdfError::Parse`] or, for an
//! inertia, [`UrdfError::Model`]): a misspelt `<axiss>` would otherwise leave the axis at x.
//! What leaves no model to build is an error in both modes: text that is not XML, a root other than
//! `<robot>`, a number that is not one (or NaN limits), an unknown joint type, a joint naming a
//! missing link, links that do not form one tree, a negative or non-finite mass.
//! Elements and attributes in an XML namespace (`xacro:`, Drake's `drake:`) are a tool's and are
//! read past without a warning, as are `<transmission>`, `<gazebo>`, `<material>` and `<sensor>`
//! under `<robot>`, PyBullet's `<contact>` in a link and vendors' attributes on `<limit>` and
//! `<dynamics>` (Franka writes `D`, `K`, `mu_coulomb`).
//!
//! ## Extension: universal and hinge2 joints
//! URDF has neither. gelenk reads an extra element, a direct child of `<robot>`, that standard
//! parsers ignore (as they ignore `<gazebo>`), and declares the joint itself as a standard
//! `revolute` or `continuous` joint about the first axis, so other tools still load the model
//! (with one rotation instead of two):
//!
//! ```xml
//! <joint name="hip" type="continuous"> <!-- axis 1, fixed in the parent -->
//!   <parent link="pelvis"/> <child link="thigh"/> <axis xyz="1 0 0"/>
//! </joint>
//! <gelenk joint="hip" type="universal" axis2="0 1 0" lower2="-1" upper2="1"/>
//!
//! <joint name="front_left" type="continuous"> <!-- steering axis -->
//!   <parent link="chassis"/> <child link="wheel_fl"/> <axis xyz="0 0 1"/>
//!   <limit lower="-0.6" upper="0.6" effort="50" velocity="5"/>
//! </joint>
//! <gelenk joint="front_left" type="hinge2" axis2="0 1 0"
//!         suspension_stiffness="20000" suspension_damping="800"
//!         suspension_lower="-0.1" suspension_upper="0.1"/>
//! ```
//! `axis2` is in the child frame. For hinge2, giving `suspension_stiffness` (N/m) adds the
//! suspension travel coordinate along axis 1 (q = [s, θ₁, θ₂]); `suspension_damping` (N·s/m)
//! defaults to 0. The `<limit>` of the joint applies to axis 1 (steering); `lower2`/`upper2`
//! to axis 2.
//!
//! ## Extension: ball-joint limits
//! A `spherical` joint takes anatomical limits ([`crate::model::BallLimits`]): a swing cone of
//! half-angle `swing` (rad) about `twist_axis` (joint frame, default `0 0 1`) and a twist range
//! `[twist_lower, twist_upper]` (rad, default ±π) about it, and a bound `angle` (rad, default π:
//! none) on the total rotation angle (MuJoCo's ball-joint `range`):
//!
//! ```xml
//! <joint name="neck" type="spherical"><parent link="chest"/><child link="head"/></joint>
//! <gelenk joint="neck" type="ball" twist_axis="0 0 1" swing="0.7" twist_lower="-0.6" twist_upper="0.6"/>
//! ```

use crate::collision::MeshOptions;
use crate::error::{CollisionError, ModelError};
use crate::io::limits::ReadLimits;
use crate::model::ranges::Num;
use crate::model::{InertiaIssue, Model};
use std::path::Path;
use thiserror::Error;

mod build;
mod extension;
mod inertia;
mod read;

/// Options for loading a URDF model.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfOptions {
    /// Attach the root link to the world by a free joint (floating base) instead of fixing it.
    pub floating_base: bool,
    /// Name of the joint that attaches the root link to the world.
    pub root_joint_name: String,
    /// Every warning is an error instead (for checking one's own files).
    pub strict: bool,
    /// Replace an inconsistent link inertia by its balanced form ([`crate::model::RigidInertia::balanced`],
    /// MuJoCo's `balanceinertia`); the warning stays. Without it the inertia is kept as written.
    pub balance_inertia: bool,
    /// Replace the rotational inertia of each link that has mass and collision shapes by that of
    /// its collision shapes as one uniform solid (meshes as their convex hulls), keeping the
    /// file's mass and centre of mass: PyBullet's default (without `URDF_USE_INERTIA_FROM_FILE`).
    /// Meshes are opened at load time, with [`UrdfOptions::meshes`].
    pub inertia_from_collision: bool,
    /// How collision meshes are found and read for [`UrdfOptions::inertia_from_collision`]
    /// (search paths for `package://` URIs; whether a missing mesh is an error or left out).
    pub meshes: MeshOptions,
    /// Largest file and deepest element nesting read ([`ReadLimits`]).
    pub limits: ReadLimits,
}

impl Default for UrdfOptions {
    fn default() -> Self {
        Self {
            floating_base: false,
            root_joint_name: "root_joint".to_string(),
            strict: false,
            balance_inertia: false,
            inertia_from_collision: false,
            meshes: MeshOptions::default(),
            limits: ReadLimits::default(),
        }
    }
}

impl UrdfOptions {
    /// Default options with a free joint at the root.
    pub fn floating() -> Self {
        Self { floating_base: true, ..Self::default() }
    }

    /// Default options where every warning is an error.
    pub fn strict() -> Self {
        Self { strict: true, ..Self::default() }
    }
}

/// What the lenient loader read past or changed, with the element and line it concerns.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfWarning {
    /// The element concerned, as `<tag name="…">` (or `<tag>`); `document` for text around it.
    pub element: String,
    /// Line in the file (1-based).
    pub line: usize,
    /// What was found and what was done.
    pub kind: WarningKind,
}

/// The kinds of [`UrdfWarning`].
#[derive(Clone, Debug, PartialEq)]
pub enum WarningKind {
    /// A child element URDF does not define in its parent (a vendor's or tool's extension): read past.
    UnknownElement {
        /// The child's tag.
        tag: String,
        /// The parent's tag.
        parent: String,
        /// The children URDF defines there, comma-separated.
        known: String,
    },
    /// An attribute URDF does not define on this element: ignored.
    UnknownAttribute {
        /// The attribute's name.
        attribute: String,
        /// The attributes URDF defines there, comma-separated.
        known: String,
    },
    /// A second child element where URDF allows one (or a second shape in a `<geometry>`): read
    /// past, the first counts (as in urdfdom).
    RepeatedElement {
        /// The repeated child's tag.
        tag: String,
    },
    /// A value URDF requires is missing: the default is used.
    MissingValue {
        /// The attribute or element missing.
        what: String,
        /// What is used instead.
        default: String,
    },
    /// A number attribute with text after its number(s), or words that are not numbers, or more
    /// numbers than it takes: read as `read`.
    ExtraText {
        /// The attribute.
        attribute: String,
        /// The value read.
        read: String,
    },
    /// Text XML does not allow around the document (whitespace before the XML declaration, NUL
    /// bytes after the root element): removed.
    StrayText {
        /// What was removed.
        what: String,
    },
    /// A lower position limit above the upper one: the joint has no position limit (Bullet's
    /// convention for an unlimited axis).
    InvertedLimits {
        /// Lower bound (rad or m).
        lower: f64,
        /// Upper bound (rad or m).
        upper: f64,
    },
    /// A positive mass below [`crate::model::ranges::MIN_POSITIVE_MASS`]: kept, but the mass
    /// matrix may be too ill-conditioned to solve beside ordinary links.
    TinyMass {
        /// The mass (kg).
        mass: f64,
    },
    /// A link's rotational inertia that no rigid body can have.
    InconsistentInertia {
        /// What is wrong with it.
        issue: InertiaIssue,
        /// Whether it was replaced by its balanced form ([`UrdfOptions::balance_inertia`]).
        balanced: bool,
    },
    /// A link with mass whose rotational inertia is singular (a point mass, a rod: a principal
    /// moment at most 1e-9 of the largest): kept as written. A free body or a subtree whose only
    /// inertia about some axis is this one has a singular mass matrix.
    SingularInertia {
        /// Principal moments, ascending (kg·m²).
        moments: [f64; 3],
        /// Whether the link has collision shapes to compute an inertia from
        /// ([`UrdfOptions::inertia_from_collision`]).
        has_collision: bool,
    },
}

impl std::fmt::Display for UrdfWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} at line {}: ", self.element, self.line)?;
        match &self.kind {
            WarningKind::UnknownElement { tag, parent, known } => {
                write!(f, "unknown element <{tag}> read past (URDF's <{parent}> has {known})")
            }
            WarningKind::UnknownAttribute { attribute, known } => {
                write!(f, "unknown attribute `{attribute}` ignored (URDF's element has {known})")
            }
            WarningKind::RepeatedElement { tag } => {
                write!(f, "a second <{tag}> read past (the first one counts)")
            }
            WarningKind::MissingValue { what, default } => write!(f, "{what} missing: {default} used"),
            WarningKind::StrayText { what } => write!(f, "{what} removed"),
            WarningKind::ExtraText { attribute, read } => {
                write!(f, "attribute `{attribute}` has text that is not its number(s): read as \"{read}\"")
            }
            WarningKind::InvertedLimits { lower, upper } => {
                let (lower, upper) = (Num(*lower), Num(*upper));
                write!(f, "<limit lower=\"{lower}\" upper=\"{upper}\">: lower above upper, read as no position limit")
            }
            WarningKind::TinyMass { mass } => write!(
                f,
                "mass {} kg is below {} kg: kept, but the dynamics may be ill-conditioned",
                Num(*mass),
                Num(crate::model::ranges::MIN_POSITIVE_MASS)
            ),
            WarningKind::InconsistentInertia { issue, balanced } => {
                let done =
                    if *balanced { "balanced (all moments set to their mean)" } else { "kept as written" };
                write!(f, "{issue}: {done}")
            }
            WarningKind::SingularInertia { moments, has_collision } => {
                write!(f, "principal moments {moments:?} kg·m²: a singular inertia, kept as written")?;
                if *has_collision {
                    write!(
                        f,
                        " (PyBullet computes inertias from the collision shapes: inertia_from_collision, \
                         --inertia-from-collision)"
                    )?;
                }
                Ok(())
            }
        }
    }
}

/// A loaded model and what the lenient loader read past or changed to load it.
#[derive(Clone, Debug)]
pub struct Loaded {
    /// The model.
    pub model: Model,
    /// The warnings, in document order (inertia and limit warnings after the others).
    pub warnings: Vec<UrdfWarning>,
}

/// A URDF file that cannot become a model. Every variant names the file (`<string>` for text).
#[derive(Debug, Error)]
pub enum UrdfError {
    /// The file could not be read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File path.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not well-formed XML or not a URDF robot, or (strict mode) a warning.
    #[error("{file}: not a valid URDF document: {message}")]
    Parse {
        /// File path.
        file: String,
        /// What is wrong, naming the element and its line where there is one.
        message: String,
    },
    /// A joint element is inconsistent (unknown link, second parent, bad extension, …).
    #[error("{file}: joint `{joint}`: {what}")]
    Joint {
        /// File path.
        file: String,
        /// Joint name.
        joint: String,
        /// What is wrong.
        what: String,
    },
    /// The links do not form one tree.
    #[error("{file}: {what}")]
    Tree {
        /// File path.
        file: String,
        /// What is wrong.
        what: String,
    },
    /// The description is well-formed but the model is invalid (mass, inertia, axis, …).
    #[error("{file}: {source}")]
    Model {
        /// File path.
        file: String,
        /// The model error, naming the link or joint.
        source: ModelError,
    },
    /// A collision shape could not be built where the loader needs it
    /// ([`UrdfOptions::inertia_from_collision`]): a mesh not found or unreadable, a bad size.
    #[error("{file}: {source}")]
    Collision {
        /// File path.
        file: String,
        /// The collision error, naming the link.
        source: CollisionError,
    },
}

/// Loads a URDF file; the warnings are dropped (see [`load_file_with_warnings`]).
pub fn load_file(path: impl AsRef<Path>, options: &UrdfOptions) -> Result<Model, UrdfError> {
    load_file_with_warnings(path, options).map(|l| l.model)
}

/// Loads a URDF document from text; the warnings are dropped (see [`load_str_with_warnings`]).
pub fn load_str(text: &str, options: &UrdfOptions) -> Result<Model, UrdfError> {
    load_str_with_warnings(text, options).map(|l| l.model)
}

/// Loads a URDF file with the warnings of the lenient loader.
pub fn load_file_with_warnings(path: impl AsRef<Path>, options: &UrdfOptions) -> Result<Loaded, UrdfError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let text =
        options.limits.read_text_io(path).map_err(|source| UrdfError::Io { file: file.clone(), source })?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut loaded = load_named(&text, &file, Some(&dir), options)?;
    loaded.model.source_dir = Some(dir);
    Ok(loaded)
}

/// Loads a URDF document from text with the warnings of the lenient loader.
pub fn load_str_with_warnings(text: &str, options: &UrdfOptions) -> Result<Loaded, UrdfError> {
    load_named(text, "<string>", None, options)
}

/// Loads `text`, named `file` in errors; relative mesh paths are relative to `dir`.
fn load_named(
    text: &str,
    file: &str,
    dir: Option<&Path>,
    options: &UrdfOptions,
) -> Result<Loaded, UrdfError> {
    let parse_err = |message: String| UrdfError::Parse { file: file.to_string(), message };
    options.limits.check_len(text).map_err(parse_err)?;
    let max = options.limits.max_depth;
    crate::io::limits::with_xml_stack(
        text,
        max,
        |depth| {
            parse_err(format!(
                "elements are nested {depth} deep; at most {max} levels are supported (ReadLimits::max_depth)"
            ))
        },
        parse_err,
        || load_parsed(text, file, dir, options),
    )
}

fn load_parsed(
    text: &str,
    file: &str,
    dir: Option<&Path>,
    options: &UrdfOptions,
) -> Result<Loaded, UrdfError> {
    let parse_err = |message: String| UrdfError::Parse { file: file.to_string(), message };
    let (text, stray) = trim_stray_text(text);
    let doc = roxmltree::Document::parse(&text).map_err(|e| parse_err(e.to_string()))?;
    let mut reader = read::Reader::new(&doc, file, options.strict);
    for (what, line) in stray {
        let kind = WarningKind::StrayText { what: what.to_string() };
        let warning = UrdfWarning { element: "document".to_string(), line, kind };
        if options.strict {
            return Err(parse_err(warning.to_string()));
        }
        reader.warnings.push(warning);
    }
    let robot = reader.robot()?;
    let extensions = extension::read_extensions(&doc, file)?;
    let mut warnings = reader.warnings;
    let model =
        build::model(&robot, &extensions, file, dir, options, &mut warnings).map_err(|e| match e {
            // An unknown element under <robot> is often a misspelt <link> or <joint>: the tree error
            // then follows from it, so it names them.
            UrdfError::Tree { file, what } => {
                let unknown: Vec<String> = warnings
                    .iter()
                    .filter_map(|w| match &w.kind {
                        WarningKind::UnknownElement { tag, parent, .. } if parent == "robot" => {
                            Some(format!("<{tag}> at line {}", w.line))
                        }
                        _ => None,
                    })
                    .collect();
                let what = if unknown.is_empty() {
                    what
                } else {
                    format!(
                        "{what} (unknown elements read past: {}; a misspelt <link> or <joint>?)",
                        unknown.join(", ")
                    )
                };
                UrdfError::Tree { file, what }
            }
            other => other,
        })?;
    Ok(Loaded { model, warnings })
}

/// `text` with an XML declaration that follows whitespace blanked out, and without NUL bytes
/// after the root element (tinyxml, under urdfdom and PyBullet, accepts both; XML does not), with
/// what was removed and its line. Blanking keeps every line number.
fn trim_stray_text(text: &str) -> (std::borrow::Cow<'_, str>, Vec<(&'static str, usize)>) {
    let mut stray = Vec::new();
    let end = text.trim_end_matches(|c: char| c == '\0' || c.is_whitespace());
    let mut out = std::borrow::Cow::Borrowed(text);
    if text[end.len()..].contains('\0') {
        stray.push(("NUL bytes after the root element", end.lines().count().max(1)));
        out = std::borrow::Cow::Borrowed(end);
    }
    let start = out.trim_start();
    if start.len() < out.len() && start.starts_with("<?xml") {
        if let Some(close) = start.find("?>") {
            let at = out.len() - start.len();
            let line = out[..at].lines().count() + usize::from(out[..at].ends_with('\n'));
            stray.push(("an XML declaration after whitespace", line.max(1)));
            let mut owned = out.into_owned();
            owned.replace_range(at..at + close + 2, &" ".repeat(close + 2));
            out = std::borrow::Cow::Owned(owned);
        }
    }
    (out, stray)
}
