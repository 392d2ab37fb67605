//! The worked example `closed_loop` as a test: on the reference axes, with the paper's
//! gains, the sync controller must lower both Track-RMSE and Sync-RMSE against standard PD,
//! and the figures must stay in the range the example documents (docs/control.md).

#[path = "../../../examples/closed_loop.rs"]
mod closed_loop;

#[test]
fn sync_controller_beats_pd_on_the_reference_axes() {
    let (pd, sync) = closed_loop::results().expect("runs");
    assert_eq!(pd.samples, 4000);
    assert!(
        sync.sync_rmse < pd.sync_rmse,
        "sync {} vs pd {}",
        sync.sync_rmse,
        pd.sync_rmse
    );
    assert!(
        sync.track_rmse < pd.track_rmse,
        "sync {} vs pd {}",
        sync.track_rmse,
        pd.track_rmse
    );
    // Same order as the paper's Table 1 (PD 0.23267 / 0.0039154 rad).
    assert!((0.1..0.4).contains(&pd.track_rmse), "{}", pd.track_rmse);
    assert!((0.001..0.01).contains(&pd.sync_rmse), "{}", pd.sync_rmse);
    // The sync reduction is substantial (paper: 49.270 %).
    let reduction = 1.0 - sync.sync_rmse / pd.sync_rmse;
    assert!(reduction > 0.3, "sync-RMSE reduction {reduction}");
    // Nothing saturated: the loop is in the linear range of the ±10 V drives.
    assert!(
        pd.axes
            .iter()
            .all(|a| a.saturations == 0 && a.peak_u < 10.0)
    );
}
