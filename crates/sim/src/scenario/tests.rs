use super::*;

fn err(text: &str) -> String {
    Scenario::from_toml(text, "test.toml")
        .expect_err("should fail")
        .to_string()
}

#[test]
fn builtin_equals_the_defaults() {
    let text = builtin("paper-2015").expect("built in");
    let s = Scenario::from_toml(text, "paper-2015").expect("valid");
    assert_eq!(s, Scenario::default());
    assert_eq!(s.axes_count(), 4);
    assert_eq!(s.ring_params(), RingParams::default());
    // The reference axes are the plant crate's.
    let models = s.axis_models().expect("axes");
    let want = ringsync_plant::reference::axes(Some(SignModel::Exact)).expect("reference");
    assert_eq!(models, want);
}

#[test]
fn an_empty_file_is_the_reference() {
    assert_eq!(
        Scenario::from_toml("", "empty").expect("valid"),
        Scenario::default()
    );
}

#[test]
fn a_partial_file_overrides_only_its_keys() {
    let s = Scenario::from_toml(
        "name = \"pd-8\"\n[ring]\nslaves = 8\ncycle = \"2ms\"\n[control]\nlaw = \"pd\"\nkp = [1.0, 2.0]\n",
        "partial",
    )
    .expect("valid");
    assert_eq!(s.ring.slaves, 8);
    assert_eq!(s.ring.cycle, Dur(Duration::from_ms(2)));
    assert_eq!(s.ring.t_rest, Ring::default().t_rest);
    assert_eq!(s.control.law, LawKind::Pd);
    // Lists are used in turn: 8 axes from 2 gains and 4 axis tables.
    assert_eq!(s.gains().kp, vec![1.0, 2.0, 1.0, 2.0, 1.0, 2.0, 1.0, 2.0]);
    assert_eq!(s.axis_models().expect("axes").len(), 8);
}

#[test]
fn unknown_keys_name_the_key_and_the_line() {
    let e = err("[ring]\nslaves = 4\nslavez = 5\n");
    assert!(e.contains("line 3") && e.contains("slavez"), "{e}");
    let e = err("[rign]\nslaves = 4\n");
    assert!(e.contains("rign"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
}

#[test]
fn bad_syntax_and_bad_types() {
    let e = err("[ring\nslaves = 4\n");
    assert!(e.starts_with("test.toml: line 1"), "{e}");
    let e = err("[ring]\nslaves = \"four\"\n");
    assert!(e.contains("line 2") && e.contains("slaves"), "{e}");
    let e = err("[ring]\ncycle = \"1000\"\n");
    assert!(e.contains("has no unit"), "{e}");
    let e = err("[control]\nlaw = \"pid\"\n");
    assert!(e.contains("pid") && e.contains("sync"), "{e}");
    let e = err("[control]\nestimator = \"kalman\"\n");
    assert!(e.contains("expected hold, linear or paper"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
    assert_eq!(
        err("[control]\nkp = []\n"),
        "control.kp = [] is out of range: allowed a number or a non-empty list"
    );
}

#[test]
fn out_of_range_values_name_key_value_and_range() {
    assert_eq!(
        err("[ring]\nslaves = 0\n"),
        "ring.slaves = 0 is out of range: allowed 1..=65535"
    );
    assert_eq!(
        err("[faults]\nloss = 1.5\n"),
        "faults.loss = 1.5 is out of range: allowed 0 ..= 1 (a probability)"
    );
    assert_eq!(
        err("[control]\nkd = [1.0, -2.0]\n"),
        "control.kd (axis 1) = -2 is out of range: allowed > 0 V·s/rad"
    );
    let e = err("[[axis]]\nviscous = -1e-5\n");
    assert_eq!(
        e,
        "axis[0].viscous = -0.00001 is out of range: allowed >= 0 N·m·s/rad"
    );
    let e = err("[clock]\ndrift_ppm = -3.0\n");
    assert!(e.starts_with("clock.drift_ppm = -3"), "{e}");
    let e = err("[ring]\ncycle = \"100us\"\n");
    assert!(e.starts_with("ring.cycle") && e.contains("short by"), "{e}");
    let e = err("[trajectory]\nkind = \"trapezoid\"\ndistance = 3.0\nv_max = 15.0\na_max = 0.0\n");
    assert!(e.starts_with("trajectory.a_max = 0"), "{e}");
}

#[test]
fn encoder_counts_must_fit_the_wire() {
    // The cosine reaches 9.6 rad: 2^31 counts per revolution would overflow the i32 field.
    let e = err("[[axis]]\nencoder_bits = 31\n");
    assert!(
        e.starts_with("axis[0].encoder_bits = 31 is out of range: allowed 1 ..= 30"),
        "{e}"
    );
    Scenario::from_toml("[[axis]]\nencoder_bits = 24\n", "ok").expect("valid");
}

#[test]
fn coupled_controllers_need_two_axes() {
    let e = err("[ring]\nslaves = 1\n");
    assert!(
        e.contains("ring.slaves = 1") && e.contains("coupling needs two axes"),
        "{e}"
    );
    // Standard PD runs a single axis.
    Scenario::from_toml("[ring]\nslaves = 1\n[control]\nlaw = \"pd\"\n", "one").expect("valid");
}

#[test]
fn unknown_names_and_files() {
    let e = Scenario::load("paper-2016")
        .expect_err("unknown")
        .to_string();
    assert!(e.contains("paper-2016") && e.contains("paper-2015"), "{e}");
    assert!(Scenario::load("paper-2015").is_ok());
}
