//! Reading scenarios: the built-in ones by name, files by path (at most 1 MiB of UTF-8),
//! TOML text with syntax errors placed by line and column, and the hash that names the
//! exact input in every output.

use super::error::{ECHO_CHARS, ScenarioError, clip, toml_message};
use super::schema::Scenario;

/// Largest scenario file read \[bytes\]: 1 MiB.
pub const MAX_SCENARIO_BYTES: u64 = 1 << 20;

/// The built-in scenarios: (name, TOML text).
const BUILTIN: &[(&str, &str)] = &[
    (
        "paper-2015",
        include_str!("../../../../scenarios/paper-2015.toml"),
    ),
    (
        "arm-2link",
        include_str!("../../../../scenarios/arm-2link.toml"),
    ),
    (
        "circle-xy",
        include_str!("../../../../scenarios/circle-xy.toml"),
    ),
    (
        "gantry-xyy",
        include_str!("../../../../scenarios/gantry-xyy.toml"),
    ),
];

/// Names of the built-in scenarios.
pub fn builtin_names() -> impl Iterator<Item = &'static str> {
    BUILTIN.iter().map(|(n, _)| *n)
}

/// The commented TOML text of a built-in scenario.
pub fn builtin(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// "line L, column C" of byte offset `at` in `text`.
fn line_col(text: &str, at: usize) -> (usize, usize) {
    let before = &text[..at.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Line `l` (1-based) of `text` as an error echoes it: a `key = value` line inside a table
/// gets the table's path, so that it reads as the dotted key a user would `--set`
/// (`ring.slaves = "two"`, `axis[1].u_max = "x"` for the second `[[axis]]` table); headers,
/// top-level keys and the inner lines of a multi-line value are echoed as they are.
fn echo_line(text: &str, l: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let src = lines.get(l.wrapping_sub(1)).copied().unwrap_or("").trim();
    let is_key = src.split_once('=').is_some_and(|(k, _)| {
        let k = k.trim();
        !k.is_empty()
            && k.chars()
                .all(|c| c.is_ascii_alphanumeric() || "_-.\"".contains(c))
    });
    if !is_key {
        return src.to_string();
    }
    // The last table header above the line, and for an array of tables its index.
    let mut tables = Tables::default();
    for line in lines.iter().take(l.saturating_sub(1)) {
        tables.see(line);
    }
    let path = tables.current;
    if path.is_empty() {
        src.to_string()
    } else {
        format!("{path}.{src}")
    }
}

/// The scenario's tables, each `[name]` once, and its one array of tables, `[[axis]]`.
const TABLES: &[&str] = &[
    "ring",
    "clock",
    "faults",
    "control",
    "trajectory",
    "plant",
    "monitor",
    "machine",
];

/// When `text` is TOML whose sections have the wrong shape (`[[ring]]` for `[ring]`,
/// `[axis]` for `[[axis]]`), what to write instead: serde's own word for it ("invalid type:
/// map, expected u32") names neither.
fn wrong_shape(text: &str) -> Option<String> {
    let t: toml::Table = toml::from_str(text).ok()?;
    for name in TABLES {
        if let Some(toml::Value::Array(_)) = t.get(*name) {
            return Some(format!(
                "{name} is one table, written [{name}], not an array of tables [[{name}]]"
            ));
        }
    }
    match t.get("axis") {
        Some(toml::Value::Table(_)) => {
            Some("axis is an array of tables, one per axis, written [[axis]], not [axis]".into())
        }
        _ => None,
    }
}

impl Scenario {
    /// Parses and validates a scenario from TOML text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, ScenarioError> {
        let s: Scenario = toml::from_str(text).map_err(|e| {
            if let Some(message) = wrong_shape(text) {
                return ScenarioError::Syntax {
                    origin: clip(origin, ECHO_CHARS).into_owned(),
                    message,
                };
            }
            let msg = toml_message(e.message());
            let message = match e.span() {
                Some(span) => {
                    let (l, c) = line_col(text, span.start);
                    let src = echo_line(text, l);
                    format!("line {l}, column {c} ({}): {msg}", clip(&src, ECHO_CHARS))
                }
                None => msg,
            };
            ScenarioError::Syntax {
                origin: clip(origin, ECHO_CHARS).into_owned(),
                message,
            }
        })?;
        let mut s = s;
        // Relative file names in it (a part program) are the scenario file's neighbours.
        let file = std::path::Path::new(origin);
        if file.is_file() {
            s.dir = Some(match file.parent() {
                Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                _ => std::path::PathBuf::from("."),
            });
            // A file that names nothing is run and reported under its own name, not the
            // reference scenario's (issue 41).
            let named = toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("name"));
            if !named && let Some(stem) = file.file_stem().and_then(|n| n.to_str()) {
                s.name = stem.to_string();
            }
        }
        s.validate().map_err(|e| match e {
            // A value out of range in a file: where in it (issue 41: "faults.loss = 1.5"
            // named neither file nor line).
            ScenarioError::OutOfRange {
                key,
                value,
                allowed,
            } if file.is_file() => {
                let allowed = match key_line(text, &key) {
                    Some(l) => format!("{allowed} ({origin}, line {l})"),
                    None => allowed,
                };
                ScenarioError::OutOfRange {
                    key,
                    value,
                    allowed,
                }
            }
            other => other,
        })?;
        Ok(s)
    }

    /// A built-in scenario by name, or a scenario file by path.
    pub fn load(name_or_path: &str) -> Result<Self, ScenarioError> {
        Scenario::load_with_hash(name_or_path).map(|(s, _)| s)
    }

    /// [`Scenario::load`], with the FNV-1a 64-bit hash of the scenario's text (it names the
    /// exact input in every output).
    pub fn load_with_hash(name_or_path: &str) -> Result<(Self, u64), ScenarioError> {
        let text = Scenario::text(name_or_path)?;
        let s = Scenario::from_toml(&text, name_or_path)?;
        Ok((s, fnv1a(text.as_bytes())))
    }

    /// The TOML text of a built-in scenario or a scenario file.
    pub fn text(name_or_path: &str) -> Result<String, ScenarioError> {
        if let Some(text) = builtin(name_or_path) {
            return Ok(text.to_string());
        }
        use std::io::Read as _;
        let path = std::path::Path::new(name_or_path);
        let shown = clip(name_or_path, ECHO_CHARS).into_owned();
        if !path.exists() {
            let names: Vec<&str> = builtin_names().collect();
            return Err(ScenarioError::Unknown(shown, names.join(", ")));
        }
        let io = |reason: String| ScenarioError::Io {
            path: shown.clone(),
            reason,
        };
        // At most 1 MiB + 1 byte: /dev/zero or an endless pipe ends here, not in memory.
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|f| f.take(MAX_SCENARIO_BYTES + 1).read_to_end(&mut bytes))
            .map_err(|e| io(e.to_string()))?;
        if bytes.len() as u64 > MAX_SCENARIO_BYTES {
            return Err(io(format!(
                "larger than 1 MiB ({MAX_SCENARIO_BYTES} bytes), the limit for a scenario file"
            )));
        }
        String::from_utf8(bytes).map_err(|e| {
            io(format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ))
        })
    }
}

/// The table a line of TOML text is in, as a dotted key names it: `faults`, or `axis[1]`
/// for the second `[[axis]]` table.
#[derive(Default)]
struct Tables {
    current: String,
    counts: std::collections::BTreeMap<String, usize>,
}

impl Tables {
    /// Takes in the next line; whether it is a table header.
    fn see(&mut self, line: &str) -> bool {
        let t = line.trim();
        if let Some(name) = t.strip_prefix("[[").and_then(|r| r.split_once("]]")) {
            let name = name.0.trim().to_string();
            let k = self.counts.entry(name.clone()).or_insert(0);
            self.current = format!("{name}[{k}]");
            *k += 1;
            true
        } else if let Some(name) = t.strip_prefix('[').and_then(|r| r.split_once(']')) {
            self.current = name.0.trim().to_string();
            true
        } else {
            false
        }
    }
}

/// The line (1-based) of `text` that sets the dotted `key` of an error (`faults.loss`,
/// `axis[2].u_max` for the third `[[axis]]` table, `control.kp (axis 3)`,
/// `machine.axes.X.drives`): the line `leaf = …` under the table the rest names; `None`
/// when the text does not set it (a default, or a key set by its table's parent).
pub fn key_line(text: &str, key: &str) -> Option<usize> {
    let key = key.split(" (").next().unwrap_or(key);
    let (table, leaf) = match key.rsplit_once('.') {
        Some((t, l)) => (t.to_string(), l),
        None => (String::new(), key),
    };
    let mut tables = Tables::default();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if tables.see(line) {
            continue;
        }
        if tables.current == table
            && let Some((k, _)) = t.split_once('=')
            && k.trim().trim_matches('"') == leaf
        {
            return Some(i + 1);
        }
    }
    None
}

/// FNV-1a, 64 bits.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}
