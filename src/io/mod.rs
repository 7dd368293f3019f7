//! Files in and out: [`urdf`] models (with gelenk's extension for universal and hinge2 joints),
//! [`mjcf`] scenes (MuJoCo's XML), [`scene`] files (TOML: a world described in text), and
//! [`problem`] files (constraint problems written for regression tests and other solvers), and
//! [`states`] files (joint states for `gelenk dynamics`). Every reader is bounded by [`limits`].

pub mod limits;
pub mod mjcf;
pub mod problem;
pub mod scene;
pub mod states;
pub mod urdf;

/// An XML element as errors name it: `<tag name="…"> at line N` (or `<tag> at line N`).
pub(crate) fn describe_element(doc: &roxmltree::Document, node: roxmltree::Node) -> String {
    let line = doc.text_pos_at(node.range().start).row;
    match node.attribute("name") {
        Some(n) => format!("<{} name=\"{n}\"> at line {line}", node.tag_name().name()),
        None => format!("<{}> at line {line}", node.tag_name().name()),
    }
}
