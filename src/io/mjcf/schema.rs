//! MuJoCo's schema of the elements gelenk reads: every attribute MuJoCo knows, with how gelenk
//! treats it (read, ignored, or refused unless it has MuJoCo's default value).

/// How gelenk treats one of MuJoCo's attributes of an element.
#[derive(Clone, Copy)]
pub(super) enum Treatment {
    /// Read (or checked where it is read).
    Read,
    /// Without effect on what gelenk simulates: names, looks, MuJoCo's solver settings and the
    /// softness of its constraints (gelenk's contacts and limits are hard), actuator limits.
    Ignored,
    /// Changes the dynamics or the contacts in a way gelenk cannot represent, unless it has the
    /// value given here (MuJoCo's default; numbers compared as numbers).
    UnlessDefault(&'static str),
}

use Treatment::{Ignored, Read, UnlessDefault};

const ORIENTATION: [(&str, Treatment); 5] =
    [("quat", Read), ("axisangle", Read), ("euler", Read), ("xyaxes", Read), ("zaxis", Read)];

/// MuJoCo 4.0's attributes of the elements gelenk reads (its schema, as `mj_loadXML` checks it),
/// with how gelenk treats each; `None` for elements gelenk does not read. A joint or geom inside
/// `<default>` has the attributes of one in a body less `name` and `class`.
pub(super) fn schema(element: &str) -> Option<Vec<(&'static str, Treatment)>> {
    let list: Vec<(&'static str, Treatment)> = match element {
        "compiler" => vec![
            ("angle", Read),
            ("eulerseq", Read),
            ("inertiafromgeom", Read),
            ("autolimits", Read),
            ("settotalmass", Read),
            ("coordinate", Read),
            ("boundmass", Read),
            ("boundinertia", Read),
            ("discardvisual", Read),
            ("balanceinertia", UnlessDefault("false")),
            ("alignfree", UnlessDefault("false")),
            ("inertiagrouprange", UnlessDefault("0 5")),
            ("meshdir", Ignored),
            ("texturedir", Ignored),
            ("assetdir", Ignored),
            ("strippath", Ignored),
            ("fitaabb", Ignored),
            ("fusestatic", Ignored),
            ("saveinertial", Ignored),
            ("usethread", Ignored),
            ("savecanonical", Ignored),
            ("savecompiled", Ignored),
            ("passthrough", Ignored),
            ("conflict", Ignored),
        ],
        "option" => vec![
            ("timestep", Read),
            ("gravity", Read),
            ("cone", Read),
            ("density", UnlessDefault("0")),
            ("viscosity", UnlessDefault("0")),
            ("wind", Ignored), // acts only through density and viscosity
            ("magnetic", Ignored),
            ("integrator", Ignored),
            ("impratio", Ignored),
            ("tolerance", Ignored),
            ("ls_tolerance", Ignored),
            ("noslip_tolerance", Ignored),
            ("ccd_tolerance", Ignored),
            ("iterations", Ignored),
            ("ls_iterations", Ignored),
            ("noslip_iterations", Ignored),
            ("ccd_iterations", Ignored),
            ("sdf_iterations", Ignored),
            ("sdf_initpoints", Ignored),
            ("jacobian", Ignored),
            ("solver", Ignored),
            ("actuatorgroupdisable", Ignored),
            ("sleep_tolerance", Ignored),
            ("o_margin", Ignored), // the o_* apply only with the override flag, refused below
            ("o_solref", Ignored),
            ("o_solimp", Ignored),
            ("o_friction", Ignored),
        ],
        "flag" => vec![
            ("gravity", Read),
            ("contact", Read),
            ("constraint", UnlessDefault("enable")),
            ("limit", UnlessDefault("enable")),
            ("frictionloss", UnlessDefault("enable")),
            ("damper", UnlessDefault("enable")),
            ("filterparent", UnlessDefault("enable")),
            ("override", UnlessDefault("disable")),
            ("equality", Ignored), // equality constraints are refused where they appear
            ("spring", Ignored),   // joint springs are refused where they appear
            ("actuation", Ignored),
            ("clampctrl", Ignored),
            ("warmstart", Ignored),
            ("refsafe", Ignored),
            ("sensor", Ignored),
            ("midphase", Ignored),
            ("eulerdamp", Ignored),
            ("autoreset", Ignored),
            ("nativeccd", Ignored),
            ("diagexact", Ignored),
            ("speculative", Ignored),
            ("ipc", Ignored),
            ("energy", Ignored),
            ("fwdinv", Ignored),
            ("invdiscrete", Ignored),
            ("multiccd", Ignored),
            ("island", Ignored),
            ("sleep", Ignored),
        ],
        "body" => vec![
            ("name", Read),
            ("childclass", Read),
            ("pos", Read),
            ("mocap", Read),
            ("gravcomp", Read),
            ("user", Ignored),
            ("fuse", Ignored),
            ("simple", Ignored),
            ("sleep", Ignored),
        ],
        "frame" => vec![("name", Ignored), ("childclass", Read), ("pos", Read)],
        "inertial" => vec![("pos", Read), ("mass", Read), ("diaginertia", Read), ("fullinertia", Read)],
        "freejoint" => vec![("name", Read), ("group", Ignored), ("align", UnlessDefault("false"))],
        "joint" => vec![
            ("name", Read),
            ("class", Read),
            ("type", Read),
            ("pos", Read),
            ("axis", Read),
            ("limited", Read),
            ("range", Read),
            ("damping", Read),
            ("frictionloss", Read),
            ("armature", Read),
            ("stiffness", Read),
            ("ref", Read),
            ("springdamper", UnlessDefault("0 0")),
            ("springref", Ignored), // acts only through stiffness, refused unless zero
            ("springyield", Ignored),
            ("margin", Ignored),
            ("solreflimit", Ignored),
            ("solimplimit", Ignored),
            ("solreffriction", Ignored),
            ("solimpfriction", Ignored),
            ("actuatorfrclimited", Ignored),
            ("actuatorfrcrange", Ignored),
            ("actuatorgravcomp", Ignored),
            ("group", Ignored),
            ("user", Ignored),
        ],
        "geom" => vec![
            ("name", Read),
            ("class", Read),
            ("type", Read),
            ("size", Read),
            ("fromto", Read),
            ("pos", Read),
            ("density", Read),
            ("mass", Read),
            ("friction", Read),
            ("contype", Read),
            ("conaffinity", Read),
            ("condim", UnlessDefault("3")),
            ("margin", UnlessDefault("0")),
            ("gap", UnlessDefault("0")),
            ("priority", UnlessDefault("0")),
            ("shellinertia", UnlessDefault("false")),
            ("adhesion", UnlessDefault("0")),
            ("surfacevel", UnlessDefault("0 0 0")),
            ("fluidshape", Ignored), // acts only through option density and viscosity
            ("fluidcoef", Ignored),
            ("solref", Ignored),
            ("solimp", Ignored),
            ("solmix", Ignored),
            ("mesh", Ignored), // mesh and height-field geoms are refused by type
            ("hfield", Ignored),
            ("fitscale", Ignored),
            ("material", Ignored),
            ("rgba", Ignored),
            ("group", Ignored),
            ("castshadow", Ignored),
            ("user", Ignored),
        ],
        "exclude" => vec![("name", Ignored), ("body1", Read), ("body2", Read)],
        "default" => vec![("class", Read)],
        _ => return None,
    };
    let oriented = matches!(element, "body" | "frame" | "inertial" | "geom");
    Some(list.into_iter().chain(ORIENTATION.into_iter().filter(|_| oriented)).collect())
}

/// Whether an attribute's value equals `default`: as numbers when both parse as numbers.
pub(super) fn equals_default(value: &str, default: &str) -> bool {
    let numbers = |t: &str| t.split_whitespace().map(str::parse::<f64>).collect::<Result<Vec<_>, _>>();
    match (numbers(value), numbers(default)) {
        (Ok(a), Ok(b)) if !a.is_empty() => a == b,
        _ => value.trim() == default,
    }
}
