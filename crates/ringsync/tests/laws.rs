//! The law registry through the library's front door: every registered law is checked and
//! simulated, a law's own parameters reach every path (sweep, reproduce, the lumped-only
//! plan's per-slave laws), and a case that sets a parameter its law lacks is named.

use ringsync::Verdict;
use ringsync::layers::control::law::LAWS;
use ringsync::sweep::SweepAxis;
use ringsync::{Duration, SimOptions};

fn short(text: &str) -> ringsync::Loaded {
    ringsync::parse(&format!("duration = \"300ms\"\n{text}"), "laws-test").expect("valid")
}

/// `ringsync check` runs the discrete-time check on each registered law with its defaults
/// (docs/control.md, "Adding a law"): every one is shown stable on the reference ring, but
/// the contour law, whose coupling follows the path and vanishes where the check
/// linearises: that one is "not shown", for the reason it names.
#[test]
fn every_registered_law_is_checked_and_stable_with_its_defaults() {
    for e in LAWS {
        let s = short(&format!("[control]\nlaw = \"{}\"\n", e.name)).scenario;
        let r = ringsync::check(&s, 11).unwrap_or_else(|err| panic!("{}: {err}", e.name));
        if e.name == "ccc" {
            assert_eq!(r.verdict(), Verdict::NotShown, "{}", e.name);
            assert_eq!(
                r.not_modelled,
                Some(ringsync::layers::model::check::NotModelled::PathDependentLaw)
            );
        } else {
            assert_eq!(r.verdict(), Verdict::Stable, "{}", e.name);
        }
    }
}

/// `--set control.params.kx=…` builds the nested table; the cases differ as the gain does.
#[test]
fn a_sweep_sets_a_laws_own_parameter() {
    let base = short("[control]\nlaw = \"adjacent\"\n");
    let axes: Vec<SweepAxis> = vec!["control.params.kx=0,6".parse().expect("axis")];
    let cases = ringsync::sweep::cases(&base, &axes, 1, false).expect("cases");
    assert_eq!(cases.len(), 2);
    let r: Vec<f64> = cases
        .iter()
        .map(|c| ringsync::sweep::run_case(c).expect("run").sync_rmse)
        .collect();
    assert!(r[1] < 0.8 * r[0], "K_X = 6 couples: {r:?}");
}

/// A case whose law does not take a parameter of the product is refused before any run,
/// naming the case.
#[test]
fn a_case_setting_a_parameter_its_law_lacks_is_named() {
    let base = short("");
    let axes: Vec<SweepAxis> = ["control.law=adjacent,pd", "control.params.kx=6"]
        .iter()
        .map(|a| a.parse().expect("axis"))
        .collect();
    let e = ringsync::sweep::cases(&base, &axes, 1, false).expect_err("pd has no kx");
    let text = e.to_string();
    assert!(e.is_usage(), "{text}");
    assert!(
        text.contains("with control.law=pd control.params.kx=6")
            && text.contains("control.params.kx is not a parameter of control.law = \"pd\""),
        "{text}"
    );
}

/// The reproduction swaps the law of its base: a base with the adjacent law's own
/// parameters still reproduces (the other laws do not take them).
#[test]
fn reproduce_runs_from_a_base_with_law_parameters() {
    let s = short("[control]\nlaw = \"adjacent\"\n[control.params]\nkx = 6.0\n").scenario;
    let opts = ringsync::ReproOptions {
        seeds: 1,
        ..Default::default()
    };
    let r = ringsync::reproduce_with(&s, &opts).expect("reproduce");
    assert_eq!(r.rows.len(), 6);
}

/// In the lumped-only plan every slave runs the law itself: its own parameters reach them.
/// K_X = K_XD = 0 is PD with feed-forward, so it matches `pd` to rounding; the default
/// coupling does not.
#[test]
fn the_lumped_only_plans_slaves_get_the_laws_parameters() {
    let run = |control: &str| {
        let mut s = short(&format!(
            "[ring]\nplan = \"lumped-only\"\n[control]\n{control}"
        ))
        .scenario;
        s.duration.0 = Duration::from_ms(500);
        ringsync::simulate(&s, &SimOptions::default())
            .expect("run")
            .summary
            .sync_rmse
    };
    let pd = run("law = \"pd\"\n");
    let zero = run("law = \"adjacent\"\n[control.params]\nkx = 0.0\nkxd = 0.0\n");
    let coupled = run("law = \"adjacent\"\n");
    assert!((zero / pd - 1.0).abs() < 1e-9, "{zero} vs pd {pd}");
    assert!((coupled / pd - 1.0).abs() > 0.05, "{coupled} vs pd {pd}");
}
