//! Where a scene came from, and how errors point into its text: byte offsets to line, column and
//! the path of the key (`body[2].mass`).

use super::{Location, SceneError};
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The text of a scene and where it came from (kept to rebuild the world).
#[derive(Clone, Debug)]
pub(super) struct Source {
    /// The file as errors name it (`<string>` for text).
    pub(super) file: String,
    /// The file's path, when loaded from one.
    pub(super) path: Option<PathBuf>,
    /// The file's stem: the scene's name unless `name` is set.
    pub(super) stem: String,
    /// The scene's text.
    pub(super) text: String,
    /// Directory that relative paths in the scene resolve against.
    pub(super) base_dir: PathBuf,
}

impl Source {
    /// Where byte `span.start` is: line, column and key path.
    pub(super) fn location(&self, span: Range<usize>) -> Location {
        let offset = span.start.min(self.text.len());
        let before = &self.text[..offset];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |k| k + 1);
        let column = before[line_start..].chars().count() + 1;
        Location { file: self.file.clone(), line, column, key: key_path(&self.text, offset) }
    }

    /// A [`SceneError::Invalid`] at `span`.
    pub(super) fn invalid(&self, span: Range<usize>, message: impl Into<String>) -> SceneError {
        SceneError::Invalid { at: self.location(span), message: message.into() }
    }

    /// `path` resolved against the scene's directory.
    pub(super) fn resolve(&self, path: &str) -> PathBuf {
        let p = Path::new(path);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base_dir.join(p)
        }
    }
}

/// The path of the innermost key or value of `text` containing byte `offset`.
fn key_path(text: &str, offset: usize) -> String {
    use toml::de::{DeTable, DeValue};
    enum Segment {
        Key(String),
        Index(usize),
    }
    fn in_table(t: &DeTable<'_>, offset: usize, path: &mut Vec<Segment>) -> bool {
        for (k, v) in t.iter() {
            path.push(Segment::Key(k.get_ref().to_string()));
            if k.span().contains(&offset) || in_value(v, offset, path) {
                return true;
            }
            path.pop();
        }
        false
    }
    fn in_value(v: &Spanned<DeValue<'_>>, offset: usize, path: &mut Vec<Segment>) -> bool {
        match v.get_ref() {
            DeValue::Table(t) if in_table(t, offset, path) => return true,
            DeValue::Array(a) => {
                for (i, e) in a.iter().enumerate() {
                    path.push(Segment::Index(i));
                    if in_value(e, offset, path) {
                        return true;
                    }
                    path.pop();
                }
            }
            _ => {}
        }
        v.span().contains(&offset)
    }
    let (root, _) = DeTable::parse_recoverable(text);
    let mut path = Vec::new();
    in_table(root.get_ref(), offset, &mut path);
    let mut out = String::new();
    for segment in path {
        match segment {
            Segment::Key(k) => {
                if !out.is_empty() {
                    out.push('.');
                }
                if !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
                    out.push_str(&k);
                } else {
                    out.push_str(&format!("{k:?}"));
                }
            }
            Segment::Index(i) => out.push_str(&format!("[{i}]")),
        }
    }
    out
}
