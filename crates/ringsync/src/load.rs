//! Loading a scenario: a built-in name (`paper-2015`), a file path, or TOML text. What comes
//! back is validated, with the hash of its text that names the exact input in every output.

use ringsync_model::Scenario;
use ringsync_model::scenario::fnv1a;

use crate::error::Result;

/// A scenario as loaded.
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    /// The scenario, validated.
    pub scenario: Scenario,
    /// Where it came from: the built-in name, the path, or the origin given with the text.
    pub origin: String,
    /// Its TOML text (a sweep's cases are made from it).
    pub text: String,
    /// FNV-1a 64-bit hash of the text.
    pub hash: u64,
}

impl Loaded {
    /// Whether it is a built-in scenario (a file of that name is not looked at).
    pub fn is_builtin(&self) -> bool {
        ringsync_model::builtin(&self.origin).is_some()
    }
}

/// Loads a built-in scenario by name or a scenario file by path.
///
/// ```
/// let l = ringsync::load("paper-2015")?;
/// assert_eq!(l.scenario.axes_count(), 4);
/// assert!(l.is_builtin());
/// // A missing file names the built-in scenarios.
/// let e = ringsync::load("no-such-file.toml").unwrap_err();
/// assert!(e.is_usage() && e.to_string().contains("paper-2015"));
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn load(name_or_path: &str) -> Result<Loaded> {
    let text = Scenario::text(name_or_path)?;
    parse(&text, name_or_path)
}

/// Parses and validates TOML text; `origin` names it in errors and outputs. Every key is
/// optional (a missing one takes the reference scenario's value).
///
/// ```
/// let l = ringsync::parse("duration = \"0.5s\"\n[ring]\nslaves = 2\n", "inline")?;
/// assert_eq!(l.scenario.axes_count(), 2);
/// let e = ringsync::parse("[ring]\nslaves = 0\n", "inline").unwrap_err();
/// assert!(e.to_string().contains("ring.slaves"), "{e}");
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn parse(text: &str, origin: &str) -> Result<Loaded> {
    let scenario = Scenario::from_toml(text, origin)?;
    Ok(Loaded {
        scenario,
        origin: origin.to_string(),
        hash: fnv1a(text.as_bytes()),
        text: text.to_string(),
    })
}

/// `base` with each `(dotted key, value)` set and validated again, as `ringsync sweep --set`
/// makes a case (the same keys, values and errors; a value is one TOML value, a bare word a
/// string). The origin names the values, e.g. `paper-2015 with control.law=pd`; the hash is
/// the new text's. No values: `base` as it is.
///
/// ```
/// let base = ringsync::load("paper-2015")?;
/// let pd = ringsync::with_values(&base, &[("control.law".into(), "pd".into())])?;
/// assert_eq!(pd.scenario.control.law, "pd");
/// assert_eq!(pd.origin, "paper-2015 with control.law=pd");
/// let e = ringsync::with_values(&base, &[("control.alpha".into(), "-1".into())]).unwrap_err();
/// assert!(e.is_usage() && e.to_string().contains("control.alpha"), "{e}");
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn with_values(base: &Loaded, items: &[(String, String)]) -> Result<Loaded> {
    if items.is_empty() {
        return Ok(base.clone());
    }
    let axes = items
        .iter()
        .map(|(k, v)| {
            let mut a: crate::sweep::SweepAxis = format!("{k}=0").parse()?;
            a.values = vec![v.clone()];
            Ok(a)
        })
        .collect::<Result<Vec<_>>>()?;
    let case = crate::sweep::set_cases(base, &axes)?
        .into_iter()
        .next()
        .ok_or_else(|| crate::Error::Failed("no case was made".into()))?;
    let labels: Vec<String> = case
        .labels
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    parse(
        &case.scenario,
        &format!("{} with {}", base.origin, labels.join(" ")),
    )
}

/// Parses `KEY=VALUE` (a `--set` option of `ringsync sim`) into (key, value); the value is
/// one TOML value, a bare word a string.
///
/// ```
/// assert_eq!(ringsync::key_value("control.law=pd")?, ("control.law".into(), "pd".into()));
/// assert!(ringsync::key_value("control.law").is_err());
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn key_value(kv: &str) -> Result<(String, String)> {
    if let Some((k, v)) = kv.split_once('=') {
        crate::sweep::one_line(k.trim(), v)?;
    }
    kv.split_once('=')
        .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
        .filter(|(k, v)| !k.is_empty() && !v.is_empty())
        .ok_or_else(|| {
            crate::Error::Input(format!(
                "'{kv}': expected KEY=VALUE, e.g. --set control.law=pd"
            ))
        })
}
