//! Bounds on what a reader accepts: the size of a file and the nesting depth of its elements.
//!
//! Every reader (URDF, MJCF, scene TOML, states JSON, problem JSON) reads at most
//! [`ReadLimits::max_bytes`] bytes of a file and refuses a larger one with a typed error before
//! allocating for more, so that `/dev/zero`, a FIFO or a runaway generator ends at once instead of
//! filling memory. XML documents nested deeper than [`ReadLimits::max_depth`] are refused before
//! parsing (the XML parser is recursive); JSON and TOML are refused past
//! [`ReadLimits::max_data_depth`]. The page `docs/reliability.md` lists the defaults.

use std::io::Read;
use std::path::Path;

/// Size and nesting bounds of a reader; [`Default`] gives the documented limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// Largest file read, in bytes (default 64 MiB).
    pub max_bytes: u64,
    /// Deepest element nesting of an XML document (URDF, MJCF; default 10 000).
    pub max_depth: usize,
    /// Deepest nesting of arrays and tables in JSON and TOML (default 128, serde_json's own).
    pub max_data_depth: usize,
}

/// Default [`ReadLimits::max_bytes`]: 64 MiB, far above any robot or scene description.
pub const DEFAULT_MAX_BYTES: u64 = 64 << 20;
/// Default [`ReadLimits::max_depth`] of XML elements.
pub const DEFAULT_MAX_DEPTH: usize = 10_000;
/// Default [`ReadLimits::max_data_depth`] of JSON and TOML.
pub const DEFAULT_MAX_DATA_DEPTH: usize = 128;

impl Default for ReadLimits {
    fn default() -> Self {
        Self {
            max_bytes: DEFAULT_MAX_BYTES,
            max_depth: DEFAULT_MAX_DEPTH,
            max_data_depth: DEFAULT_MAX_DATA_DEPTH,
        }
    }
}

/// Why a bounded read failed.
#[derive(Debug)]
pub enum BoundedReadError {
    /// The operating system's error (missing file, permission, not UTF-8 as `InvalidData`).
    Io(std::io::Error),
    /// The file holds more than the limit.
    TooLarge {
        /// The limit, in bytes.
        limit: u64,
    },
}

impl std::fmt::Display for BoundedReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "{e}"),
            Self::TooLarge { limit } => {
                write!(f, "larger than the limit of {limit} bytes (ReadLimits::max_bytes)")
            }
        }
    }
}

impl std::error::Error for BoundedReadError {}

impl From<BoundedReadError> for std::io::Error {
    fn from(e: BoundedReadError) -> Self {
        match e {
            BoundedReadError::Io(e) => e,
            BoundedReadError::TooLarge { .. } => {
                std::io::Error::new(std::io::ErrorKind::FileTooLarge, e.to_string())
            }
        }
    }
}

impl ReadLimits {
    /// Reads the UTF-8 text of `path`, at most [`Self::max_bytes`] of it: a longer file (or an
    /// endless one, `/dev/zero`) is [`BoundedReadError::TooLarge`] after reading one byte more.
    pub fn read_text(&self, path: &Path) -> Result<String, BoundedReadError> {
        let file = std::fs::File::open(path).map_err(BoundedReadError::Io)?;
        let hint = file.metadata().map(|m| m.len()).unwrap_or(0);
        if hint > self.max_bytes {
            return Err(BoundedReadError::TooLarge { limit: self.max_bytes });
        }
        let mut bytes = Vec::with_capacity(hint as usize);
        file.take(self.max_bytes.saturating_add(1)).read_to_end(&mut bytes).map_err(BoundedReadError::Io)?;
        if bytes.len() as u64 > self.max_bytes {
            return Err(BoundedReadError::TooLarge { limit: self.max_bytes });
        }
        String::from_utf8(bytes)
            .map_err(|e| BoundedReadError::Io(std::io::Error::new(std::io::ErrorKind::InvalidData, e)))
    }

    /// [`Self::read_text`] with the error as an [`std::io::Error`] (`FileTooLarge` for the limit),
    /// for readers whose error type carries one.
    pub fn read_text_io(&self, path: &Path) -> std::io::Result<String> {
        self.read_text(path).map_err(Into::into)
    }

    /// `Err` with a message when `text` is longer than [`Self::max_bytes`] (for text given in memory).
    pub fn check_len(&self, text: &str) -> Result<(), String> {
        if text.len() as u64 > self.max_bytes {
            return Err(format!(
                "{} bytes: larger than the limit of {} bytes (ReadLimits::max_bytes)",
                text.len(),
                self.max_bytes
            ));
        }
        Ok(())
    }

    /// `Err` with a message when the arrays and tables of a JSON or TOML `text` nest deeper than
    /// [`Self::max_data_depth`] (an upper bound: brackets in strings and comments are skipped).
    pub fn check_data_depth(&self, text: &str) -> Result<(), String> {
        let depth = data_depth(text, self.max_data_depth);
        if depth > self.max_data_depth {
            return Err(format!(
                "arrays and tables nested more than {} deep (ReadLimits::max_data_depth)",
                self.max_data_depth
            ));
        }
        Ok(())
    }
}

/// Nesting depth of `[` and `{` in JSON or TOML text outside strings and `#` comments, stopping
/// once it passes `stop`.
fn data_depth(text: &str, stop: usize) -> usize {
    let b = text.as_bytes();
    let (mut depth, mut max) = (0usize, 0usize);
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'"' | b'\'' => {
                let q = b[i];
                i += 1;
                while i < b.len() && b[i] != q && b[i] != b'\n' {
                    if q == b'"' && b[i] == b'\\' {
                        i += 1;
                    }
                    i += 1;
                }
            }
            b'#' => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'[' | b'{' => {
                depth += 1;
                max = max.max(depth);
                if max > stop {
                    return max;
                }
            }
            b']' | b'}' => depth = depth.saturating_sub(1),
            _ => {}
        }
        i += 1;
    }
    max
}

/// An upper bound of the element nesting depth of an XML text (comments, CDATA, processing
/// instructions, declarations and quoted attribute values skipped), without parsing.
pub(crate) fn xml_depth(text: &str) -> usize {
    let b = text.as_bytes();
    let find = |from: usize, pat: &[u8]| {
        b[from.min(b.len())..]
            .windows(pat.len())
            .position(|w| w == pat)
            .map_or(b.len(), |p| from + p + pat.len())
    };
    let (mut i, mut depth, mut max) = (0, 0usize, 0);
    while i < b.len() {
        if b[i] != b'<' {
            i += 1;
        } else if b[i..].starts_with(b"<!--") {
            i = find(i + 4, b"-->");
        } else if b[i..].starts_with(b"<![CDATA[") {
            i = find(i + 9, b"]]>");
        } else if b[i..].starts_with(b"<?") {
            i = find(i + 2, b"?>");
        } else if b[i..].starts_with(b"<!") {
            i = find(i + 2, b">");
        } else if b[i..].starts_with(b"</") {
            depth = depth.saturating_sub(1);
            i = find(i + 2, b">");
        } else {
            // A start tag: up to the `>` outside quotes; `/>` closes it at once.
            let mut quote = None;
            let mut j = i + 1;
            while j < b.len() {
                match (quote, b[j]) {
                    (None, b'"' | b'\'') => quote = Some(b[j]),
                    (Some(q), c) if c == q => quote = None,
                    (None, b'>') => break,
                    _ => {}
                }
                j += 1;
            }
            if j >= b.len() || b[j - 1] != b'/' {
                depth += 1;
                max = max.max(depth);
            }
            i = j + 1;
        }
    }
    max
}

/// Element nesting that the XML parser (recursive) handles on any thread's stack.
const SHALLOW: usize = 100;
/// Stack reserved per nesting level when parsing a deep document on its own thread.
const STACK_PER_LEVEL: usize = 32 * 1024;

/// Runs `parse` (which parses `text` as XML and reads it) on a stack deep enough for the
/// document's nesting: on this thread for a shallow document, on a thread of its own otherwise.
/// A document nested deeper than `max_depth` is `Err(too_deep(depth))` without parsing; a thread
/// that cannot be made is `Err(no_thread(message))`.
pub(crate) fn with_xml_stack<T, E: Send>(
    text: &str,
    max_depth: usize,
    too_deep: impl FnOnce(usize) -> E,
    no_thread: impl FnOnce(String) -> E,
    parse: impl FnOnce() -> Result<T, E> + Send,
) -> Result<T, E>
where
    T: Send,
{
    let depth = xml_depth(text);
    if depth > max_depth {
        return Err(too_deep(depth));
    }
    if depth <= SHALLOW {
        return parse();
    }
    std::thread::scope(|scope| {
        let handle = std::thread::Builder::new()
            .name("gelenk-xml".to_string())
            .stack_size((depth + 64) * STACK_PER_LEVEL)
            .spawn_scoped(scope, parse);
        match handle {
            Ok(h) => h.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            Err(e) => Err(no_thread(format!("no thread to parse a document nested {depth} deep: {e}"))),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dev_zero_is_refused_at_the_limit() {
        let limits = ReadLimits { max_bytes: 1 << 20, ..ReadLimits::default() };
        let path = Path::new("/dev/zero");
        if path.exists() {
            let start = std::time::Instant::now();
            assert!(
                matches!(limits.read_text(path), Err(BoundedReadError::TooLarge { limit }) if limit == 1 << 20)
            );
            assert!(start.elapsed().as_secs_f64() < 1.0);
        }
    }

    #[test]
    fn data_depth_skips_strings_and_comments() {
        assert_eq!(data_depth(r#"{"a": "[[[[", "b": [[1]]} # [[[["#, 100), 3);
        assert_eq!(data_depth("x = [[[1]]]\n'[[['", 100), 3);
        assert_eq!(data_depth(&"[".repeat(1000), 10), 11);
    }

    #[test]
    fn xml_depth_counts_open_elements() {
        assert_eq!(xml_depth("<a><b/><c><d x='>'></d></c><!-- <e> --></a>"), 3);
    }
}
