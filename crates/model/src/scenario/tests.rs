use super::*;
use error::plant_error;
use ringsync_plant::SignModel;
use ringsync_proto::{Duration, RingParams};

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
    assert_eq!(s.control.law, "pd");
    // Lists are used in turn: 8 axes from 2 gains and 4 axis tables.
    assert_eq!(s.gains().kp, vec![1.0, 2.0, 1.0, 2.0, 1.0, 2.0, 1.0, 2.0]);
    assert_eq!(s.axis_models().expect("axes").len(), 8);
}

/// A partial `[trajectory]` is the reference cosine with what it gives; a trapezoid needs
/// its keys, and keys of another kind are refused.
#[test]
fn a_partial_trajectory_table_takes_the_reference_cosine() {
    let s = Scenario::from_toml("[trajectory]\nperiod = \"3s\"\n", "t").expect("valid");
    let r = Scenario::default();
    match (&s.trajectory, &r.trajectory) {
        (
            TrajectorySpec::Cosine { peak_speed, period },
            TrajectorySpec::Cosine { peak_speed: p0, .. },
        ) => {
            assert_eq!(*peak_speed, *p0);
            assert_eq!(period.0, Duration::from_ms(3000));
        }
        other => panic!("{other:?}"),
    }
    let e = err("[trajectory]\nkind = \"trapezoid\"\ndistance = 3.0\nv_max = 1.0\n");
    assert!(e.contains("missing field `a_max`"), "{e}");
    let e = err("[trajectory]\nperiod = \"3s\"\ndistance = 3.0\n");
    assert!(
        e.contains("unknown field `distance` for kind = \"cosine\""),
        "{e}"
    );
    let e = err("[trajectory]\nkind = \"spiral\"\n");
    assert!(e.contains("unknown variant `spiral`"), "{e}");
    let e = err("[trajectory]\nperiodd = \"3s\"\n");
    assert!(e.contains("periodd"), "{e}");
}

/// A syntax or type error echoes its line as the dotted key (`axis[1].u_max = …`).
#[test]
fn errors_echo_the_dotted_key() {
    let e = err("[[axis]]\nu_max = 5\n[[axis]]\nu_max = \"x\"\n");
    assert!(
        e.contains("line 4, column 9 (axis[1].u_max = \"x\")"),
        "{e}"
    );
    let e = err("seed = \"x\"\n[ring]\nslaves = 2\n");
    assert!(e.contains("(seed = \"x\")"), "{e}");
    let e = err("[ring]\nslavez = 5\n");
    assert!(e.contains("(ring.slavez = 5)"), "{e}");
    let e = err(
        "[trajectory]\nkind = \"sequence\"\ntargets = [\n  [1.0, \"x\"],\n]\nv_max = 1.0\na_max = 1.0\n",
    );
    assert!(!e.contains("trajectory.[1.0"), "{e}");
}

/// A section of the wrong shape says which shape it needs.
#[test]
fn sections_of_the_wrong_shape_say_which_they_need() {
    let e = err("[[ring]]\nslaves = 2\n");
    assert_eq!(
        e,
        "test.toml: ring is one table, written [ring], not an array of tables [[ring]]"
    );
    let e = err("[axis]\nu_max = 5\n");
    assert!(e.contains("written [[axis]], not [axis]"), "{e}");
}

/// Messages name the key the user wrote and keep huge values short.
#[test]
fn messages_name_the_written_key_in_short_numbers() {
    let e = err("[trajectory]\npeak_speed = 0\n");
    assert!(e.starts_with("trajectory.peak_speed = 0 "), "{e}");
    let e = err("[[axis]]\nu_max = 0\n");
    assert!(e.starts_with("axis[0].u_max = 0 "), "{e}");
    let e = err("[trajectory]\npeak_speed = 1e300\n");
    assert!(e.contains("velocities up to 2.0e300 rad/s"), "{e}");
    assert!(e.len() < 400, "{e}");
    let e = err("[ring]\ncycle = \"1s\"\n");
    assert!(
        e.contains("once a cycle of ring.cycle = 1000000.000 µs")
            && e.contains("loop factor is 101.987"),
        "{e}"
    );
    let e = err("[[axis]]\nrated_torque = nan\n");
    assert!(e.starts_with("axis[0].rated_torque = NaN "), "{e}");
    let e = err("[[axis]]\n[[axis]]\nj_over_ka = -1\n");
    assert!(e.starts_with("axis[1].j_over_ka = -1 "), "{e}");
    let e = err("duration = \"0.5ms\"\n");
    assert!(
        e.starts_with("duration = ") && e.contains("at least one cycle"),
        "{e}"
    );
    assert!(Scenario::from_toml("duration = \"1ms\"\n", "t").is_ok());
    let e = err("[faults]\nsilent_slave = 1\nsilent_from = \"-1s\"\n");
    assert!(e.starts_with("faults.silent_from = "), "{e}");
    let e = err("[ring]\nslaves = 65535\n");
    assert!(
        e.contains("ring.cycle = \"1000.000 µs\" is out of range: allowed at least ")
            && e.contains("for 65535 slaves (the plan's eq. 1;"),
        "{e}"
    );
}

/// A gain list longer than the ring would leave values unused: refused, named.
#[test]
fn a_gain_list_longer_than_the_ring_is_refused() {
    let e = err("[control]\nkp = [1, 2, 3, 4, 5]\n");
    assert!(
        e.contains("control.kp = [1, 2, 3, 4, 5]") && e.contains("at most 4"),
        "{e}"
    );
    let e = err("[ring]\nslaves = 2\n[control]\nlaw = \"pd\"\nkd = [1, 2, 3]\n");
    assert!(e.contains("control.kd") && e.contains("at most 2"), "{e}");
    assert!(Scenario::from_toml("[control]\nkp = [1, 2, 3, 4]\n", "t").is_ok());
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
    // A huge or tiny number is echoed in scientific notation, not as hundreds of digits.
    assert_eq!(
        err("[faults]\nloss = 1e300\n"),
        "faults.loss = 1e300 is out of range: allowed 0 ..= 1 (a probability)"
    );
    let e = err("[clock]\ndrift_ppm = -1e300\n");
    assert!(
        e.starts_with("clock.drift_ppm = -1e300 is out of range"),
        "{e}"
    );
    let e = err("[faults]\nbrake_gain = -1e-300\n");
    assert!(
        e.starts_with("faults.brake_gain = -1e-300 is out of range"),
        "{e}"
    );
    // Gains (and α) beyond 10¹²: ke = 1e308 made the lumped-only plan's commands NaN (a
    // trace of NaN, no stop) and stopped the proposed plan for "no response".
    assert_eq!(
        err("[control]\nke = 1e308\n"),
        "control.ke (axis 1) = 1e308 is out of range: allowed >= 0 ..= 1e12 V·s/rad"
    );
    assert_eq!(
        err("[control]\nalpha = 1e308\n"),
        "control.alpha = 1e308 is out of range: allowed >= 0 ..= 1e12 (dimensionless)"
    );
    assert!(Scenario::from_toml("[control]\nkp = 1e12\nalpha = 1e12\n", "t").is_ok());
    // The same where a duration is given as a number: short, and saying a unit is needed.
    let e = err("[trajectory]\nperiod = 1e300\n");
    assert!(e.contains("1e300 has no unit") && e.len() < 200, "{e}");
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
        "control.kd (axis 2) = -2 is out of range: allowed > 0 ..= 1e12 V·s/rad"
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
    assert_eq!(
        err("[control]\nvelocity = \"observer\"\nobserver_bandwidth = 600.0\n"),
        "control.observer_bandwidth = 600 is out of range: allowed > 0 Hz ..= 500 Hz (half the cycle rate)"
    );
    assert_eq!(
        err("[control]\ndob_bandwidth = 20.0\n"),
        "control.kh (axis 1) = 0 is out of range: allowed > 0 V·s²/rad: the disturbance observer inverts the nominal model K_H"
    );
    let e = err("[control]\nkh = 0.016\nkf = 0.2\ndob_bandwidth = 20.0\n");
    assert!(
        e.starts_with("control.kf = 0.2") && e.contains("twice"),
        "{e}"
    );
    let e = err("[control]\nkh = 0.016\ndob_bandwidth = 900.0\n");
    assert!(e.starts_with("control.dob_bandwidth = 900"), "{e}");
    assert_eq!(
        err("[control]\nkf = [0.2, -0.1]\n"),
        "control.kf (axis 2) = -0.1 is out of range: allowed >= 0 ..= 1e12 V"
    );
    // A duration without its unit says so (issue 41: it said "expected a string").
    let e = err("duration = 4\n");
    assert!(e.contains("4 has no unit") && e.contains("\"4s\""), "{e}");
    let e = err("[ring]\ncycle = 0.001\n");
    assert!(e.contains("0.001 has no unit"), "{e}");
    // Axes are numbered from 1 in every message, as in the outputs: the third gain is
    // axis 3's (issue 41: messages numbered axes from 0).
    assert_eq!(
        err("[control]\nkp = [3.0, 3.0, -1.0, 3.0]\n"),
        "control.kp (axis 3) = -1 is out of range: allowed > 0 ..= 1e12 V/rad"
    );
}

#[test]
fn encoder_counts_must_fit_the_wire() {
    // The cosine reaches 9.6 rad and 15.12 rad/s: velocities travel as i32 counts/s, so with
    // the 2× margin 2^28 counts per revolution is the most (2^29 would clamp at 25 rad/s).
    assert_eq!(
        err("[[axis]]\nencoder_bits = 30\n"),
        "axis[0].encoder_bits = 30 is out of range: allowed 2 ..= 28 for this trajectory: velocities up to 30.2 rad/s (2 × the peak speed, room for overshoot and the stop) must fit the wire's i32 counts/s"
    );
    let e = err("[[axis]]\nencoder_bits = 31\n");
    assert!(e.starts_with("axis[0].encoder_bits = 31"), "{e}");
    // The plant's encoder needs 4 counts per revolution.
    assert_eq!(
        err("[[axis]]\nencoder_bits = 1\n"),
        "axis[0].encoder_bits = 1 is out of range: allowed 2 ..= 28: an encoder needs at least 4 counts per revolution (2 bits)"
    );
    // The second table is checked too, and a faster profile allows fewer bits.
    let e = err(
        "[trajectory]\nkind = \"trapezoid\"\ndistance = 3.0\nv_max = 1000.0\na_max = 100.0\n[[axis]]\n[[axis]]\nencoder_bits = 24\n",
    );
    assert!(
        e.starts_with("axis[1].encoder_bits = 24 is out of range: allowed 2 ..= 22")
            && e.contains("velocities up to 2000.0 rad/s"),
        "{e}"
    );
    // A slow, long move is bounded by its positions instead.
    let s = Scenario::from_toml(
        "[trajectory]\nkind = \"trapezoid\"\ndistance = 5000.0\nv_max = 0.5\na_max = 1.0\n",
        "slow",
    )
    .expect("valid");
    let b = s.encoder_bits_range();
    assert_eq!(b.range, 2..=21);
    assert!(b.reason.contains("positions up to 5001.0 rad"), "{b:?}");
    for bits in [2, 20, 28] {
        Scenario::from_toml(&format!("[[axis]]\nencoder_bits = {bits}\n"), "ok").expect("valid");
    }
}

#[test]
fn every_accepted_encoder_runs_in_the_plant() {
    // What validate accepts, the simulator's encoder accepts (it wants >= 4 counts/rev).
    let s = Scenario::from_toml("[[axis]]\nencoder_bits = 2\n", "two").expect("valid");
    for a in &s.axis {
        ringsync_plant::Encoder::new(1u32 << a.encoder_bits).expect("plant accepts");
    }
}

#[test]
fn an_empty_axis_list_is_an_error_not_a_panic() {
    for law in ["sync", "pd", "ring-coupled"] {
        assert_eq!(
            err(&format!("axis = []\n[control]\nlaw = \"{law}\"\n")),
            "axis = [] is out of range: allowed at least one [[axis]] table"
        );
    }
    // The helpers that use the axes in turn do not divide by zero either.
    let s = Scenario {
        axis: Vec::new(),
        ..Scenario::default()
    };
    assert!(s.axis_spec(0).is_none());
    assert!(s.gains().u_max.iter().all(|u| u.is_nan()));
    assert!(s.law().is_err());
    assert_eq!(
        s.axis_models()
            .map_err(|(i, e)| plant_error(i, &e).to_string())
            .expect_err("no axes"),
        "axis = [] is out of range: allowed at least one [[axis]] table"
    );
}

#[test]
fn the_lumped_only_plan_is_bounded_by_its_one_frame() {
    let e = err("[ring]\nplan = \"lumped-only\"\nslaves = 60\ncycle = \"2ms\"\n");
    assert!(
        e.starts_with("ring.slaves = 60 is out of range: allowed 1 ..= 46")
            && e.contains("at most 46 slaves"),
        "{e}"
    );
}

#[test]
fn pd_honours_its_feed_forward_gains() {
    use ringsync_control::{ControlInput, ControlOutput, ErrorHistory};
    let pd = Scenario::from_toml("[control]\nlaw = \"pd\"\n", "pd").expect("valid");
    assert_eq!(pd.law_name(), "pd");
    assert_eq!(pd.law().expect("law").name(), "pd");
    let ff = Scenario::from_toml(
        "[control]\nlaw = \"pd\"\nkh = [0.0, 0.02]\nkc = 0.1\n",
        "ff",
    )
    .expect("valid");
    assert_eq!(ff.law_name(), "pd+ff");
    let law = ff.law().expect("law");
    assert_eq!(law.name(), "pd+ff");
    // Zero errors: the command is the feed-forward K_H·ẍ^d + K_C·ẋ^d alone.
    let n = ff.axes_count();
    let mut input = ControlInput::new(n, 1e-3);
    for d in &mut input.desired {
        d.v = 2.0;
        d.a = 50.0;
    }
    let mut out = ControlOutput::new(n);
    law.compute(&ErrorHistory::new(n), &input, &mut out)
        .expect("compute");
    assert_eq!(out.u_raw[0], 0.1 * 2.0);
    assert!((out.u_raw[1] - (0.02 * 50.0 + 0.1 * 2.0)).abs() < 1e-12);
    // The sync controller's name does not change.
    let sync = Scenario::from_toml("[control]\nkh = 0.01\n", "sync").expect("valid");
    assert_eq!(sync.law_name(), "sync");
}

#[test]
fn long_lines_and_values_are_cut_in_errors() {
    let long = "a".repeat(100_000);
    let e = err(&format!("[ring]\nslaves = \"{long}\"\n"));
    assert!(e.chars().count() < 500, "{} chars", e.chars().count());
    assert!(e.contains("…") && e.ends_with("expected u32"), "{e}");
    assert!(
        e.starts_with("test.toml: line 2, column 10 (ring.slaves = \"aaa"),
        "{e}"
    );
    assert_eq!(clip("abcdef", 3), "abc…");
    assert_eq!(clip("abc", 3), "abc");
    assert_eq!(clip_middle("abc", 3), "abc");
}

#[test]
fn files_over_one_mib_are_refused_unread() {
    let dir = std::env::temp_dir().join(format!("ringsync-scenario-unit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let big = dir.join("big.toml");
    let mut text = "#".repeat(MAX_SCENARIO_BYTES as usize);
    text.push('\n');
    std::fs::write(&big, &text).expect("write");
    let e = Scenario::load(big.to_str().expect("path"))
        .expect_err("too big")
        .to_string();
    assert!(
        e.ends_with("larger than 1 MiB (1048576 bytes), the limit for a scenario file"),
        "{e}"
    );
    // One byte less loads (a comment-only file is the reference).
    std::fs::write(&big, &text[1..]).expect("write");
    Scenario::load(big.to_str().expect("path")).expect("1 MiB is allowed");
    // A device that never ends stops at the limit.
    let e = Scenario::load("/dev/zero")
        .expect_err("endless")
        .to_string();
    assert!(e.contains("larger than 1 MiB"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
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

/// The slaves' brake, u = −K_b·v once a cycle, must be a stable loop on every axis: a K_b
/// too large for an axis's inertia is refused, naming the key, the axis and the factor.
#[test]
fn a_brake_gain_the_slaves_cannot_use_is_refused() {
    // Reference axis 0: J/K_a = 0.0156 s²·V/rad, T = 1 ms: K_b·T/(J/K_a) < 2 ⟺ K_b < 31.2.
    let ok = Scenario::from_toml("[faults]\nbrake_gain = 30.0\n", "test");
    assert!(ok.is_ok(), "{ok:?}");
    let e = Scenario::from_toml("[faults]\nbrake_gain = 40.0\n", "test")
        .expect_err("unstable brake")
        .to_string();
    assert!(e.starts_with("faults.brake_gain = 40"), "{e}");
    assert!(e.contains("axis[0]: its loop factor is 2.564"), "{e}");
    // A large K_D alone is the control law's business (`check` judges it), not the brake's.
    assert!(Scenario::from_toml("[control]\nkd = 159.1\n", "test").is_ok());
}

/// `control.law` is a name in the law registry and `[control.params]` holds the chosen law's
/// own parameters: bad names, keys, lengths and values are one line that names the key.
#[test]
fn laws_and_their_parameters_come_from_the_registry() {
    let adj = "[control]\nlaw = \"adjacent\"\n[control.params]\n";
    for (text, want) in [
        (
            "[control]\nlaw = \"pid\"\n".to_string(),
            "unknown control law 'pid': expected one of pd, sync, ring-coupled, adjacent",
        ),
        (
            "[control]\nlaw = \"sync\"\n[control.params]\nkx = 1.0\n".to_string(),
            "control.params.kx is not a parameter of control.law = \"sync\": its parameters are none; kx is a parameter of \"adjacent\"",
        ),
        (
            format!("{adj}kx = -1.0\n"),
            "control.params.kx = -1 is out of range: allowed >= 0 V/rad",
        ),
        (
            format!("{adj}kxd = [1, 2, -3, 4]\n"),
            "control.params.kxd (axis 3) = -3 is out of range: allowed >= 0 V·s/rad",
        ),
        (
            format!("{adj}kx = [1, 2]\n"),
            "control.params.kx = [1, 2] is out of range: allowed one number for every axis, or a list of 4 (one per axis)",
        ),
        (
            format!("{adj}kx = \"a\"\n"),
            "expected a number (the same on every axis) or a list of numbers (one per axis)",
        ),
        (
            format!("[ring]\nslaves = 1\n{adj}"),
            "ring.slaves = 1 is out of range: allowed 2 ..= 65535 with control.law = \"adjacent\" (coupling needs two axes)",
        ),
    ] {
        let e = err(&text);
        assert!(e.contains(want), "{text}: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
    }
    // Accepted: one number for every axis, or one per axis; unset keys take their defaults.
    let s = Scenario::from_toml(&format!("{adj}kx = [1, 0, 2, 0.5]\n"), "adj").expect("valid");
    let p = s.law_params().expect("params");
    assert_eq!(p.get("kx"), Some([1.0, 0.0, 2.0, 0.5].as_slice()));
    assert_eq!(
        p.get("kxd"),
        None,
        "defaults are filled in when the law is built"
    );
    assert_eq!(s.law().expect("law").name(), "adjacent");
}

/// A value out of range in a file names the file and the line that sets it (issue 41:
/// `faults.loss = 1.5` named neither); given as text it names the key as before.
#[test]
fn out_of_range_values_in_a_file_name_its_line() {
    let dir = std::env::temp_dir().join(format!("ringsync-keyline-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch");
    for (text, line) in [
        ("name = \"mine\"\n[faults]\nloss = 1.5\n", 3),
        ("[control]\nlaw = \"pd\"\nkp = [3.0, -1.0, 3.0, 3.0]\n", 3),
        ("[[axis]]\n[[axis]]\nviscous = 1e-5\nu_max = -1\n", 4),
    ] {
        let f = dir.join("bad.toml");
        std::fs::write(&f, text).expect("file");
        let origin = f.to_str().expect("utf-8");
        let e = Scenario::from_toml(text, origin)
            .expect_err(text)
            .to_string();
        assert!(
            e.ends_with(&format!("({origin}, line {line})")),
            "{text:?}: {e}"
        );
        let e = Scenario::from_toml(text, "text")
            .expect_err(text)
            .to_string();
        assert!(!e.contains("line"), "{e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A scenario file without `name` runs under its file's name, not the reference
/// scenario's (issue 41); one given as text keeps the default.
#[test]
fn a_file_without_a_name_is_named_after_the_file() {
    let dir = std::env::temp_dir().join(format!("ringsync-named-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch");
    let f = dir.join("my-ring.toml");
    std::fs::write(&f, "[ring]\nslaves = 2\n").expect("file");
    let s = Scenario::from_toml("[ring]\nslaves = 2\n", f.to_str().expect("utf-8")).expect("valid");
    assert_eq!(s.name, "my-ring");
    let named = "name = \"kept\"\n[ring]\nslaves = 2\n";
    std::fs::write(&f, named).expect("file");
    assert_eq!(
        Scenario::from_toml(named, f.to_str().expect("utf-8"))
            .expect("valid")
            .name,
        "kept"
    );
    assert_eq!(
        Scenario::from_toml("[ring]\nslaves = 2\n", "text")
            .expect("valid")
            .name,
        "paper-2015"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The reference scenario's description names no law: a run of one law is not "PD vs sync"
/// (issue 41).
#[test]
fn the_reference_description_names_no_law() {
    let d = Scenario::default().description;
    assert!(!d.contains("PD") && !d.contains("sync"), "{d}");
}
