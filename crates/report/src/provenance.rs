//! What every JSON output says about where it came from: the version of ringsync that wrote
//! it and the version of its schema (docs/schemas/ publishes the schemas).

use serde_json::{Map, Value};

/// The version of ringsync (the workspace's) that wrote an output.
pub const RINGSYNC_VERSION: &str = env!("CARGO_PKG_VERSION");

/// `v` (an object) with `ringsync_version` and `schema_version` as its first two keys;
/// anything else is returned as it is.
///
/// ```
/// let v = ringsync_report::provenance::stamp(serde_json::json!({"a": 1}), 2);
/// let keys: Vec<&String> = v.as_object().unwrap().keys().collect();
/// assert_eq!(keys, ["ringsync_version", "schema_version", "a"]);
/// assert_eq!(v["schema_version"], 2);
/// ```
pub fn stamp(v: Value, schema_version: u32) -> Value {
    let Value::Object(rest) = v else { return v };
    let mut m = Map::with_capacity(rest.len() + 2);
    m.insert("ringsync_version".into(), Value::from(RINGSYNC_VERSION));
    m.insert("schema_version".into(), Value::from(schema_version));
    for (k, v) in rest {
        if k != "ringsync_version" && k != "schema_version" {
            m.insert(k, v);
        }
    }
    Value::Object(m)
}

/// The JSON Schemas of ringsync's typed JSON outputs, generated from the types that write
/// them: (file name under docs/schemas/, schema). A test keeps the published files equal to
/// these (`RINGSYNC_BLESS=1 cargo test -p ringsync-report schemas` rewrites them).
pub fn schemas() -> Vec<(&'static str, Value)> {
    let mut out = Vec::new();
    for (name, title, mut s) in [
        (
            "reproduce-summary.json",
            "summary.json of `ringsync reproduce`",
            schemars::schema_for!(crate::repro::ReproSummary),
        ),
        (
            "run-summary.json",
            "summary.json of a run (`ringsync sim`; `ringsync rt` adds keys of its own)",
            schemars::schema_for!(crate::sim::RunSummary),
        ),
    ] {
        s.insert("title".into(), Value::from(title));
        let mut v = s.to_value();
        unescape_docs(&mut v);
        out.push((name, v));
    }
    out
}

/// Descriptions taken from the doc comments without rustdoc's escapes (`\[rad\]`).
fn unescape_docs(v: &mut Value) {
    match v {
        Value::String(s) if s.contains('\\') => *s = s.replace("\\[", "[").replace("\\]", "]"),
        Value::Array(a) => a.iter_mut().for_each(unescape_docs),
        Value::Object(m) => m.values_mut().for_each(unescape_docs),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// docs/schemas/ holds exactly the schemas the types generate.
    #[test]
    fn schemas_are_published() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/schemas");
        for (name, schema) in schemas() {
            let text = serde_json::to_string_pretty(&schema).expect("json") + "\n";
            let path = dir.join(name);
            if std::env::var_os("RINGSYNC_BLESS").is_some() {
                std::fs::create_dir_all(&dir).expect("mkdir");
                std::fs::write(&path, &text).expect("write");
            }
            let published = std::fs::read_to_string(&path).unwrap_or_default();
            assert!(
                published == text,
                "{} differs from the schema the types generate: run RINGSYNC_BLESS=1 cargo test -p ringsync-report schemas",
                path.display()
            );
        }
    }
}
