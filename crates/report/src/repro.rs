//! The reproduction of the paper's Table 1 (Huang et al. 2015, section 4) over seeds:
//! every (plan, controller) case is run once per seed, and the tables give the mean, the
//! standard deviation and the range beside the paper's single measurement, with a plain
//! verdict on what matches and what cannot.

use std::fmt::Write as _;

use ringsync_model::RunResult;
use ringsync_model::result::{ASSUMPTIONS, LUMPED_ONLY_ASSUMPTION, P2P_ASSUMPTION};
use ringsync_model::scenario::{CoulombSign, Scenario};
use schemars::JsonSchema;
use serde::Serialize;
use serde_json::Value;

use crate::sim::{esc, per_axis};

/// The paper's Table 1 (rad): (Track-RMSE this paper, ref. \[3\]; Sync-RMSE this paper, ref. \[3\]).
pub const PAPER_TABLE_1: [(&str, [f64; 4]); 2] = [
    ("standard PD", [0.23267, 0.25715, 0.0039154, 0.0059015]),
    ("sync controller", [0.18341, 0.20427, 0.0019863, 0.0032035]),
];

/// The paper's reductions of the sync controller against standard PD [%]: (Track-RMSE,
/// Sync-RMSE) on the proposed plan and on ref. [3]'s lumped-only plan (Table 1).
const PAPER_REDUCTIONS: [(&str, [f64; 2]); 2] = [
    ("p2p-lumped", [21.171, 49.270]),
    ("lumped-only", [20.564, 45.717]),
];

/// Version of the schema of `reproduce`'s summary.json ([`ReproSummary`]; docs/schemas/).
/// 1 was a bare list of cases; 2 is an object with the claims, their verdicts and provenance.
pub const REPRO_SCHEMA_VERSION: u32 = 2;

/// What "sd" means in every output of ringsync.
pub const SD_MEANING: &str = "sample standard deviation (n − 1 in the denominator; 0 for one seed)";

/// Mean, standard deviation and range of one figure over seeds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, JsonSchema)]
pub struct Spread {
    /// Values in it (seeds).
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n − 1 in the denominator; 0 for a single value).
    pub sd: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
}

impl Spread {
    /// The spread of `values` (NaN figures when there are none).
    ///
    /// ```
    /// let s = ringsync_report::repro::Spread::of(&[1.0, 2.0, 3.0]);
    /// assert_eq!((s.n, s.mean, s.sd, s.min, s.max), (3, 2.0, 1.0, 1.0, 3.0));
    /// ```
    pub fn of(values: &[f64]) -> Spread {
        let n = values.len();
        if n == 0 {
            return Spread {
                n,
                mean: f64::NAN,
                sd: f64::NAN,
                min: f64::NAN,
                max: f64::NAN,
            };
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let sd = if n > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Spread {
            n,
            mean,
            sd,
            min: values.iter().copied().fold(f64::INFINITY, f64::min),
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }

    /// Whether `v` lies within the range.
    pub fn covers(&self, v: f64) -> bool {
        self.min <= v && v <= self.max
    }

    /// `mean ± sd` with `digits` decimals.
    fn pm(&self, digits: usize) -> String {
        format!("{:.*} ± {:.*}", digits, self.mean, digits, self.sd)
    }

    /// `min–max` with `digits` decimals.
    fn range(&self, digits: usize) -> String {
        format!("{:.*}–{:.*}", digits, self.min, digits, self.max)
    }
}

/// One case of the reproduction, (plan, controller), over its seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct ReproRow {
    /// `p2p-lumped` or `lumped-only`.
    pub plan: &'static str,
    /// `pd`, `sync` or `ring-coupled`.
    pub controller: &'static str,
    /// The seeds, in run order (the scenario's seed, +1, …).
    pub seeds: Vec<u64>,
    /// Track-RMSE of each seed's run \[rad\] (eq. 26).
    pub track_rmse: Vec<f64>,
    /// Sync-RMSE of each seed's run \[rad\] (eq. 27).
    pub sync_rmse: Vec<f64>,
}

impl ReproRow {
    /// Track-RMSE over the seeds \[rad\].
    pub fn track(&self) -> Spread {
        Spread::of(&self.track_rmse)
    }

    /// Sync-RMSE over the seeds \[rad\].
    pub fn sync(&self) -> Spread {
        Spread::of(&self.sync_rmse)
    }
}

/// How much the sync controller lowers one metric against standard PD on one plan: each
/// seed's reduction 1 − sync/PD from the two runs of that seed (paired), over the seeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reduction {
    /// `p2p-lumped` or `lumped-only`.
    pub plan: &'static str,
    /// `Track-RMSE` or `Sync-RMSE`.
    pub metric: &'static str,
    /// The paper's reduction [%] (for `lumped-only`, ref. \[3\]'s, measured on another bench).
    pub paper: f64,
    /// Ours over the seeds [%].
    pub ours: Spread,
}

fn find<'a>(rows: &'a [ReproRow], plan: &str, ctl: &str) -> Option<&'a ReproRow> {
    rows.iter().find(|r| r.plan == plan && r.controller == ctl)
}

/// The reductions of the sync controller against standard PD, per plan and metric, for
/// the plans whose two rows are present.
pub fn reductions(rows: &[ReproRow]) -> Vec<Reduction> {
    let mut out = Vec::new();
    for (plan, paper) in PAPER_REDUCTIONS {
        let (Some(pd), Some(sync)) = (find(rows, plan, "pd"), find(rows, plan, "sync")) else {
            continue;
        };
        for (k, metric) in ["Track-RMSE", "Sync-RMSE"].into_iter().enumerate() {
            let (a, b) = if k == 0 {
                (&pd.track_rmse, &sync.track_rmse)
            } else {
                (&pd.sync_rmse, &sync.sync_rmse)
            };
            let per_seed: Vec<f64> = a
                .iter()
                .zip(b)
                .map(|(p, s)| (1.0 - s / p) * 100.0)
                .collect();
            out.push(Reduction {
                plan,
                metric,
                paper: paper[k],
                ours: Spread::of(&per_seed),
            });
        }
    }
    out
}

fn plan_label(plan: &str) -> &'static str {
    if plan == "lumped-only" {
        "lumped-only (ref. [3])"
    } else {
        "proposed (P2P + lumped)"
    }
}

fn controller_label(ctl: &str) -> &'static str {
    match ctl {
        "pd" => "standard PD",
        "sync" => "sync controller",
        _ => "ring-coupled (not in the paper)",
    }
}

/// The paper's (Track-RMSE, Sync-RMSE) of a case, when Table 1 has it.
fn paper_values(plan: &str, ctl: &str) -> Option<(f64, f64)> {
    let k = match ctl {
        "pd" => 0,
        "sync" => 1,
        _ => return None,
    };
    let p = PAPER_TABLE_1[k].1;
    Some(if plan == "lumped-only" {
        (p[1], p[3])
    } else {
        (p[0], p[2])
    })
}

/// Standard PD's and the sync controller's Sync-RMSE of ref. \[3\] against the paper's own
/// (Table 1): how much worse the paper found the lumped-only plan, on its other test bench.
pub const PAPER_BENCH_RATIOS: [(&str, f64); 2] = [
    ("pd", PAPER_TABLE_1[0].1[3] / PAPER_TABLE_1[0].1[2]),
    ("sync", PAPER_TABLE_1[1].1[3] / PAPER_TABLE_1[1].1[2]),
];

/// How much wider the bench experiment makes the spread of the axes' J/K_a (each axis's
/// deviation from their mean times this): the factor that raises standard PD's Sync-RMSE
/// on the lumped-only plan of `paper-2015` about as much as ref. \[3\]'s bench raised it
/// (1.51×; docs/simulator.md, "The plan comparison", fitted once over 8 seeds).
pub const BENCH_SPREAD: f64 = 1.5;

/// The bench experiment of a reproduction: the lumped-only plan on the same plant with the
/// spread of its axes' J/K_a widened [`BENCH_SPREAD`] times, standard PD and the sync
/// controller over the same seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchRows {
    /// The factor on each axis's deviation of J/K_a from the axes' mean.
    pub spread: f64,
    /// Standard PD.
    pub pd: ReproRow,
    /// The sync controller.
    pub sync: ReproRow,
}

/// How much lower one controller's Sync-RMSE is on the proposed plan than on the
/// lumped-only plan: each seed's 1 − proposed/lumped-only (same clocks, same draws).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanGap {
    /// `pd` or `sync`.
    pub controller: &'static str,
    /// The paper's [%]: its proposed plan against ref. \[3\]'s rows (another test bench).
    pub paper: f64,
    /// Ours over the seeds, on one plant [%].
    pub ours: Spread,
}

fn paired(a: &[f64], b: &[f64]) -> Spread {
    let per_seed: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(x, y)| (1.0 - y / x) * 100.0)
        .collect();
    Spread::of(&per_seed)
}

/// The plan gaps of standard PD and the sync controller, for those whose rows on both
/// plans are present.
pub fn plan_gaps(rows: &[ReproRow]) -> Vec<PlanGap> {
    let mut out = Vec::new();
    for (k, ctl) in ["pd", "sync"].into_iter().enumerate() {
        let (Some(p2p), Some(lo)) = (
            find(rows, "p2p-lumped", ctl),
            find(rows, "lumped-only", ctl),
        ) else {
            continue;
        };
        let p = PAPER_TABLE_1[k].1;
        out.push(PlanGap {
            controller: ctl,
            paper: (1.0 - p[2] / p[3]) * 100.0,
            ours: paired(&lo.sync_rmse, &p2p.sync_rmse),
        });
    }
    out
}

/// What ringsync's figures say of one of the paper's claims.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum ClaimVerdict {
    /// Ours lowers the error in every seed and the paper's figure lies within our range.
    Reproduced,
    /// Ours lowers the error in every seed, by a size whose range does not hold the paper's.
    DirectionOnly,
    /// Ours does not lower the error in every seed.
    NotReproduced,
}

impl ClaimVerdict {
    fn of(ours: &Spread, paper: f64) -> Self {
        if ours.min <= 0.0 || !ours.min.is_finite() {
            ClaimVerdict::NotReproduced
        } else if ours.covers(paper) {
            ClaimVerdict::Reproduced
        } else {
            ClaimVerdict::DirectionOnly
        }
    }

    /// The verdict in words.
    pub fn words(self) -> &'static str {
        match self {
            ClaimVerdict::Reproduced => "reproduced",
            ClaimVerdict::DirectionOnly => "direction reproduced, size not",
            ClaimVerdict::NotReproduced => "not reproduced",
        }
    }
}

/// One of the paper's claims, one figure of it, beside ours.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct Claim {
    /// `controller` (the sync controller against standard PD, on the proposed plan) or
    /// `plan` (the proposed plan against ref. \[3\]'s lumped-only plan, sync controller).
    pub claim: String,
    /// The claim as the paper makes it.
    pub statement: String,
    /// `Sync-RMSE` or `Track-RMSE`.
    pub metric: String,
    /// The paper's reduction [%].
    pub paper_percent: f64,
    /// Ours over the seeds, each seed's reduction paired [%].
    pub ours_percent: Spread,
    /// What ours says of it.
    pub verdict: ClaimVerdict,
    /// The verdict as a sentence, with the figures and why.
    pub text: String,
}

/// The paper's two claims: the sync controller's reductions of both errors against standard
/// PD on the proposed plan, and the proposed plan's lower Sync-RMSE than ref. \[3\]'s plan
/// with the sync controller (with the bench experiment's figures when it ran).
pub fn claims(rows: &[ReproRow], bench: Option<&BenchRows>) -> Vec<Claim> {
    let mut out = Vec::new();
    for r in reductions(rows)
        .iter()
        .filter(|r| r.plan == "p2p-lumped")
        .rev()
    {
        let verdict = ClaimVerdict::of(&r.ours, r.paper);
        let text = format!(
            "Claim 1, the controller ({}): the paper's sync controller lowers it by {:.3} % against standard PD; ours by {} % \
over the seeds ({} %): {}; {}.",
            r.metric,
            r.paper,
            r.ours.pm(1),
            r.ours.range(1),
            verdict.words(),
            gap_words(&r.ours, r.paper, "the paper's"),
        );
        out.push(Claim {
            claim: "controller".into(),
            statement: format!(
                "The sync controller lowers {} by {:.3} % against standard PD on the proposed plan (Table 1).",
                r.metric, r.paper
            ),
            metric: r.metric.into(),
            paper_percent: r.paper,
            ours_percent: r.ours,
            verdict,
            text,
        });
    }
    let gaps = plan_gaps(rows);
    if let Some(sync) = gaps.iter().find(|g| g.controller == "sync") {
        let verdict = ClaimVerdict::of(&sync.ours, sync.paper);
        let mut text = format!(
            "Claim 2, the plan (Sync-RMSE, sync controller): the paper's proposed plan is {:.1} % lower than ref. [3]'s lumped-only \
plan ({} against {}); on one plant ours is {} % lower ({} %): {}.",
            sync.paper,
            PAPER_TABLE_1[1].1[2],
            PAPER_TABLE_1[1].1[3],
            sync.ours.pm(1),
            sync.ours.range(1),
            verdict.words()
        );
        if let Some(pd) = gaps.iter().find(|g| g.controller == "pd") {
            text.push_str(&format!(
                " The paper's standard PD rows differ by {:.1} % as well, though PD reads only each axis's own sample, fresh on both \
plans (ours: {} %): most of the paper's gap lies between its two test benches, not its two plans.",
                pd.paper,
                pd.ours.pm(1)
            ));
        }
        if let Some(b) = bench {
            let ratio = |row: &ReproRow, ctl: &str| {
                find(rows, "p2p-lumped", ctl).map_or(f64::NAN, |p| row.sync().mean / p.sync().mean)
            };
            let red = paired(&b.pd.sync_rmse, &b.sync.sync_rmse);
            text.push_str(&format!(
                " A bench difference of that size is enough: the same plant on the lumped-only plan with its axes' J/K_a spread \
{}× wider raises our standard PD's Sync-RMSE {:.2}× (ref. [3]'s PD against the paper's: {:.2}×) and the sync controller's \
{:.2}× ({:.2}×), the controller's reduction becoming {} % (ref. [3]: {:.3} %). How ref. [3]'s slaves compute (holding the \
frame while they do), their estimator and a longer cycle move neither row that far (docs/simulator.md, \"The plan comparison\").",
                b.spread,
                ratio(&b.pd, "pd"),
                PAPER_BENCH_RATIOS[0].1,
                ratio(&b.sync, "sync"),
                PAPER_BENCH_RATIOS[1].1,
                red.pm(1),
                PAPER_REDUCTIONS[1].1[1],
            ));
        }
        out.push(Claim {
            claim: "plan".into(),
            statement: format!(
                "The proposed plan (P2P + lumped) gives the sync controller {:.1} % lower Sync-RMSE than the lumped-only plan of \
ref. [3] (Table 1; ref. [3]'s rows were measured on another test bench).",
                sync.paper
            ),
            metric: "Sync-RMSE".into(),
            paper_percent: sync.paper,
            ours_percent: sync.ours,
            verdict,
            text,
        });
    }
    out
}

/// Where the paper's figure lies against our spread: `the paper's 49.270 % lies within our
/// range (41.3–50.2 %), 4.4 points above our mean`.
fn gap_words(ours: &Spread, paper: f64, who: &str) -> String {
    let d = paper - ours.mean;
    let place = if ours.covers(paper) {
        "within"
    } else if paper > ours.max {
        "above"
    } else {
        "below"
    };
    format!(
        "{who} {paper:.3} % lies {place} our range ({} %), {:.1} points {} our mean",
        ours.range(1),
        d.abs(),
        if d < 0.0 { "below" } else { "above" }
    )
}

/// The paper's Table 1 beside ours over seeds, as Markdown: the RMSEs (mean ± sample
/// standard deviation and range) per plan and controller, the bench experiment's rows, the
/// reductions and plan gaps per seed, and the verdict on both of the paper's claims.
pub fn repro_table(rows: &[ReproRow], bench: Option<&BenchRows>) -> String {
    let mut o = String::new();
    let seeds = rows.first().map_or(0, |r| r.seeds.len());
    let _ = writeln!(
        o,
        "| plan | controller | Track, paper | Track, ringsync | range | Sync, paper | Sync, ringsync | range |"
    );
    let _ = writeln!(o, "|---|---|---:|---:|---:|---:|---:|---:|");
    let line = |o: &mut String, plan: String, r: &ReproRow, paper: Option<(f64, f64)>| {
        let (t, s) = (r.track(), r.sync());
        let _ = writeln!(
            o,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            plan,
            controller_label(r.controller),
            paper.map_or("–".into(), |p| p.0.to_string()),
            t.pm(5),
            t.range(5),
            paper.map_or("–".into(), |p| p.1.to_string()),
            s.pm(7),
            s.range(7)
        );
    };
    for plan in ["p2p-lumped", "lumped-only"] {
        for ctl in ["pd", "sync", "ring-coupled"] {
            if let Some(r) = find(rows, plan, ctl) {
                line(&mut o, plan_label(plan).into(), r, paper_values(plan, ctl));
            }
        }
    }
    if let Some(b) = bench {
        for r in [&b.pd, &b.sync] {
            let label = format!("lumped-only, J/K_a spread {}× (bench experiment)", b.spread);
            line(&mut o, label, r, paper_values("lumped-only", r.controller));
        }
    }
    let _ = writeln!(
        o,
        "\nTrack = Track-RMSE, Sync = Sync-RMSE [rad] (eq. 26-27); ringsync: mean ± sample standard deviation (n − 1) over {seeds} seed{} and the range. The paper reports one measurement per case; it measured its ref. [3] rows on another test bench, ringsync runs both plans on one plant.{}\n",
        if seeds == 1 { "" } else { "s" },
        if bench.is_some() {
            " The bench experiment runs that plant again with each axis's J/K_a moved further from the axes' mean, to see how much of the paper's plan gap a bench difference explains."
        } else {
            ""
        }
    );
    let red = reductions(rows);
    let gaps = plan_gaps(rows);
    if !red.is_empty() || !gaps.is_empty() {
        let _ = writeln!(o, "| reduction | paper | ringsync | range |");
        let _ = writeln!(o, "|---|---:|---:|---:|");
        for r in &red {
            let _ = writeln!(
                o,
                "| {}, sync controller vs standard PD, {} | {:.3} % | {} % | {} % |",
                r.metric,
                plan_label(r.plan),
                r.paper,
                r.ours.pm(3),
                r.ours.range(3)
            );
        }
        for g in &gaps {
            let _ = writeln!(
                o,
                "| Sync-RMSE, proposed vs lumped-only plan, {} | {:.3} % | {} % | {} % |",
                controller_label(g.controller),
                g.paper,
                g.ours.pm(3),
                g.ours.range(3)
            );
        }
        let _ = writeln!(
            o,
            "\nEach seed's reduction is 1 − new/old from the two runs of that seed (same clocks, same draws); the paper's plan figures compare its proposed plan with ref. [3]'s rows.\n"
        );
    }
    let _ = writeln!(o, "Verdict:\n");
    for line in verdict(rows, bench) {
        let _ = writeln!(o, "- {line}");
    }
    o
}

/// The verdict in plain sentences: each of the paper's claims beside ours (with its
/// verdict and the gap), ref. \[3\]'s own reductions, and what cannot match and why.
pub fn verdict(rows: &[ReproRow], bench: Option<&BenchRows>) -> Vec<String> {
    let mut v: Vec<String> = claims(rows, bench).into_iter().map(|c| c.text).collect();
    for r in reductions(rows).iter().filter(|r| r.plan == "lumped-only") {
        v.push(format!(
            "{}, lumped-only plan: the sync controller lowers it by {} % ({} %) against standard PD; {}.",
            r.metric,
            r.ours.pm(1),
            r.ours.range(1),
            gap_words(&r.ours, r.paper, "ref. [3]'s (another test bench)")
        ));
    }
    if let Some(pd) = find(rows, "p2p-lumped", "pd") {
        let (t, s) = (pd.track().mean, pd.sync().mean);
        let (pt, ps) = (PAPER_TABLE_1[0].1[0], PAPER_TABLE_1[0].1[2]);
        v.push(format!(
            "Absolute levels: our standard PD's Track-RMSE is {} and its Sync-RMSE {} the paper's. \
The paper does not report its motors' loads, encoders, friction or any gain beyond K_P and K_D; the reference scenario \
reconstructs them (docs/system.md, \"The reference scenario\"), so ringsync can test the reductions, not the absolute errors.",
            above_below(t, pt),
            above_below(s, ps)
        ));
    }
    v.push(
        "What cannot match: the paper's single measurement per case against our spread over seeds (the paper gives no spread), \
and the ref. [3] rows, which the paper measured on another test bench where ringsync runs both plans on one plant."
            .to_string(),
    );
    v
}

/// How far `ours` lies from `paper`, e.g. `18.9 % below`.
fn above_below(ours: f64, paper: f64) -> String {
    let d = (ours / paper - 1.0) * 100.0;
    format!(
        "{:.1} % {}",
        d.abs(),
        if d < 0.0 { "below" } else { "above" }
    )
}

/// One case of `reproduce`'s summary.json: means, sample standard deviations and ranges
/// over the seeds, every seed's values, and the paper's where Table 1 has them \[rad\].
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct CaseSummary {
    /// `p2p-lumped` or `lumped-only`.
    pub plan: String,
    /// `pd`, `sync` or `ring-coupled`.
    pub controller: String,
    /// The paper's Track-RMSE \[rad\] (Table 1; ref. \[3\]'s on the lumped-only plan).
    pub paper_track_rmse: Option<f64>,
    /// The paper's Sync-RMSE \[rad\].
    pub paper_sync_rmse: Option<f64>,
    /// Seeds run.
    pub seeds: usize,
    /// Track-RMSE, mean over the seeds \[rad\].
    pub track_rmse: f64,
    /// Its sample standard deviation (n − 1) \[rad\].
    pub track_rmse_sd: f64,
    /// Its smallest value \[rad\].
    pub track_rmse_min: f64,
    /// Its largest value \[rad\].
    pub track_rmse_max: f64,
    /// Sync-RMSE, mean over the seeds \[rad\].
    pub sync_rmse: f64,
    /// Its sample standard deviation (n − 1) \[rad\].
    pub sync_rmse_sd: f64,
    /// Its smallest value \[rad\].
    pub sync_rmse_min: f64,
    /// Its largest value \[rad\].
    pub sync_rmse_max: f64,
    /// The seeds, in run order.
    pub seed_values: Vec<u64>,
    /// Track-RMSE of each seed's run \[rad\].
    pub track_rmse_per_seed: Vec<f64>,
    /// Sync-RMSE of each seed's run \[rad\].
    pub sync_rmse_per_seed: Vec<f64>,
}

impl CaseSummary {
    fn of(r: &ReproRow, paper: Option<(f64, f64)>) -> Self {
        let (t, s) = (r.track(), r.sync());
        CaseSummary {
            plan: r.plan.into(),
            controller: r.controller.into(),
            paper_track_rmse: paper.map(|p| p.0),
            paper_sync_rmse: paper.map(|p| p.1),
            seeds: r.seeds.len(),
            track_rmse: t.mean,
            track_rmse_sd: t.sd,
            track_rmse_min: t.min,
            track_rmse_max: t.max,
            sync_rmse: s.mean,
            sync_rmse_sd: s.sd,
            sync_rmse_min: s.min,
            sync_rmse_max: s.max,
            seed_values: r.seeds.clone(),
            track_rmse_per_seed: r.track_rmse.clone(),
            sync_rmse_per_seed: r.sync_rmse.clone(),
        }
    }
}

/// One reduction in `reproduce`'s summary.json: the paper's [%] beside ours over the seeds.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct ReductionSummary {
    /// What is compared: `sync vs pd` (controllers, on `plan`) or `p2p-lumped vs
    /// lumped-only` (plans, for `controller`).
    pub compares: String,
    /// The plan (controller reductions) or `both` (plan gaps).
    pub plan: String,
    /// The controller (plan gaps) or `sync vs pd`.
    pub controller: String,
    /// `Sync-RMSE` or `Track-RMSE`.
    pub metric: String,
    /// The paper's [%].
    pub paper_percent: f64,
    /// Ours over the seeds, each seed paired [%].
    pub ours_percent: Spread,
}

/// The bench experiment in `reproduce`'s summary.json.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct BenchSummary {
    /// The factor on each axis's deviation of J/K_a from the axes' mean.
    pub spread: f64,
    /// Standard PD on the lumped-only plan of the widened bench.
    pub pd: CaseSummary,
    /// The sync controller likewise.
    pub sync: CaseSummary,
    /// PD's mean Sync-RMSE there over PD's on the proposed plan of the scenario's bench.
    pub pd_ratio: f64,
    /// The paper's: ref. \[3\]'s PD Sync-RMSE over its own.
    pub paper_pd_ratio: f64,
    /// The sync controller's ratio likewise.
    pub sync_ratio: f64,
    /// The paper's likewise.
    pub paper_sync_ratio: f64,
    /// The sync controller's reduction of Sync-RMSE against PD there [%].
    pub reduction_percent: Spread,
    /// Ref. \[3\]'s [%].
    pub paper_reduction_percent: f64,
}

/// `reproduce`'s summary.json (schema version [`REPRO_SCHEMA_VERSION`]).
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct ReproSummary {
    /// The version of ringsync that wrote it.
    pub ringsync_version: String,
    /// The version of this schema.
    pub schema_version: u32,
    /// The base scenario's name.
    pub scenario: String,
    /// The seeds of every case.
    pub seeds: Vec<u64>,
    /// What `_sd` means.
    pub sd: String,
    /// The paper's claims, each with ours and a verdict.
    pub claims: Vec<Claim>,
    /// One per (plan, controller).
    pub cases: Vec<CaseSummary>,
    /// The sync controller against standard PD per plan and metric, and each controller's
    /// Sync-RMSE on the proposed plan against the lumped-only plan.
    pub reductions: Vec<ReductionSummary>,
    /// The bench experiment, when it ran (axes whose J/K_a differ).
    pub bench: Option<BenchSummary>,
    /// The verdict's sentences, as table.md prints them.
    pub verdict: Vec<String>,
}

/// `reproduce`'s summary.json for scenario `name`.
pub fn repro_summary(name: &str, rows: &[ReproRow], bench: Option<&BenchRows>) -> ReproSummary {
    let mut reds: Vec<ReductionSummary> = reductions(rows)
        .into_iter()
        .map(|r| ReductionSummary {
            compares: "sync vs pd".into(),
            plan: r.plan.into(),
            controller: "sync vs pd".into(),
            metric: r.metric.into(),
            paper_percent: r.paper,
            ours_percent: r.ours,
        })
        .collect();
    reds.extend(plan_gaps(rows).into_iter().map(|g| ReductionSummary {
        compares: "p2p-lumped vs lumped-only".into(),
        plan: "both".into(),
        controller: g.controller.into(),
        metric: "Sync-RMSE".into(),
        paper_percent: g.paper,
        ours_percent: g.ours,
    }));
    let bench_summary = bench.map(|b| {
        let base = |ctl: &str| find(rows, "p2p-lumped", ctl).map_or(f64::NAN, |p| p.sync().mean);
        BenchSummary {
            spread: b.spread,
            pd: CaseSummary::of(&b.pd, paper_values("lumped-only", "pd")),
            sync: CaseSummary::of(&b.sync, paper_values("lumped-only", "sync")),
            pd_ratio: b.pd.sync().mean / base("pd"),
            paper_pd_ratio: PAPER_BENCH_RATIOS[0].1,
            sync_ratio: b.sync.sync().mean / base("sync"),
            paper_sync_ratio: PAPER_BENCH_RATIOS[1].1,
            reduction_percent: paired(&b.pd.sync_rmse, &b.sync.sync_rmse),
            paper_reduction_percent: PAPER_REDUCTIONS[1].1[1],
        }
    });
    ReproSummary {
        ringsync_version: crate::provenance::RINGSYNC_VERSION.into(),
        schema_version: REPRO_SCHEMA_VERSION,
        scenario: name.into(),
        seeds: rows.first().map(|r| r.seeds.clone()).unwrap_or_default(),
        sd: SD_MEANING.into(),
        claims: claims(rows, bench),
        cases: rows
            .iter()
            .map(|r| CaseSummary::of(r, paper_values(r.plan, r.controller)))
            .collect(),
        reductions: reds,
        bench: bench_summary,
        verdict: verdict(rows, bench),
    }
}

/// [`repro_summary`] as JSON.
pub fn repro_json(name: &str, rows: &[ReproRow], bench: Option<&BenchRows>) -> Value {
    serde_json::to_value(repro_summary(name, rows, bench)).unwrap_or(Value::Null)
}

/// The figures of a reproduction: (file name, SVG). Fig. 1 is the cycle's timing diagram,
/// Fig. 3 the command, Fig. 4 the position errors and Fig. 5 the sync errors per axis, for
/// standard PD and the sync controller (runs made with traces).
pub fn repro_figures(
    timing: Option<String>,
    pd: &RunResult,
    sync: &RunResult,
) -> Vec<(&'static str, String)> {
    use crate::plot::{PALETTE, line_chart};
    let mut figs = Vec::new();
    if let Some(t) = timing {
        figs.push(("fig1-cycle.svg", t));
    }
    let cmd = crate::sim::axis_series(&sync.trace, 1, |t, i| t.x_d[i])
        .finish("x^d, every axis".into(), PALETTE[0]);
    figs.push((
        "fig3-command.svg",
        line_chart(
            "Fig. 3: position command x^d(t)",
            "t [s]",
            "x^d [rad]",
            &[cmd],
        ),
    ));
    // Each pair shares its y range, so that PD's and the sync controller's errors compare
    // by eye as in the paper's Figs. 4 and 5.
    let pair = |title_a: &str,
                title_b: &str,
                y: &str,
                f: fn(&ringsync_model::result::Trace, usize) -> f64| {
        let (a, b) = (per_axis(pd, f), per_axis(sync, f));
        let range = crate::plot::extent(&a)
            .zip(crate::plot::extent(&b))
            .map(|(p, q)| (p[2].min(q[2]), p[3].max(q[3])));
        let opts = crate::plot::Chart {
            y_range: range,
            ..Default::default()
        };
        (
            crate::plot::chart(title_a, "t [s]", y, &a, &opts),
            crate::plot::chart(title_b, "t [s]", y, &b, &opts),
        )
    };
    let (a, b) = pair(
        "Fig. 4a: position errors e = x^d − x, standard PD",
        "Fig. 4b: position errors e = x^d − x, sync controller",
        "e [rad]",
        |t, i| t.e(i),
    );
    figs.push(("fig4-position-errors-pd.svg", a));
    figs.push(("fig4-position-errors-sync.svg", b));
    let (a, b) = pair(
        "Fig. 5a: synchronisation errors ε = Te, standard PD",
        "Fig. 5b: synchronisation errors ε = Te, sync controller",
        "ε [rad]",
        |t, i| t.eps[i],
    );
    figs.push(("fig5-sync-errors-pd.svg", a));
    figs.push(("fig5-sync-errors-sync.svg", b));
    figs
}

/// Markdown of tables, `- ` items and paragraphs as HTML (what [`repro_table`] writes).
fn markdown_html(md: &str) -> String {
    let mut o = String::new();
    let mut in_table = false;
    let mut in_list = false;
    for line in md.lines() {
        let cells = || line.trim().trim_matches('|').split('|').map(str::trim);
        if line.starts_with('|') {
            if line.starts_with("|---") {
                continue;
            }
            if !in_table {
                o.push_str("<table><tr>");
                for c in cells() {
                    let _ = write!(o, "<th>{}</th>", esc(c));
                }
                o.push_str("</tr>\n");
                in_table = true;
                continue;
            }
            o.push_str("<tr>");
            for c in cells() {
                let _ = write!(o, "<td>{}</td>", esc(c));
            }
            o.push_str("</tr>\n");
            continue;
        }
        if in_table {
            o.push_str("</table>\n");
            in_table = false;
        }
        if let Some(item) = line.strip_prefix("- ") {
            if !in_list {
                o.push_str("<ul>\n");
                in_list = true;
            }
            let _ = writeln!(o, "<li>{}</li>", esc(item));
            continue;
        }
        if in_list {
            o.push_str("</ul>\n");
            in_list = false;
        }
        if !line.trim().is_empty() {
            let _ = writeln!(o, "<p class=\"note\">{}</p>", esc(line));
        }
    }
    if in_table {
        o.push_str("</table>\n");
    }
    if in_list {
        o.push_str("</ul>\n");
    }
    o
}

/// One self-contained HTML page: what was run, Table 1 beside the paper's over seeds with
/// the verdict, the figures (the first seed's runs), and every assumption.
pub fn repro_html(
    s: &Scenario,
    rows: &[ReproRow],
    bench: Option<&BenchRows>,
    figures: &[(&str, String)],
) -> String {
    let mut o = String::new();
    let _ = write!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>ringsync: {name}</title>\
<style>body{{font-family:DejaVu Sans,Verdana,sans-serif;max-width:1240px;margin:2em auto;line-height:1.45;color:#222}}\
table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:4px 10px;text-align:right;white-space:nowrap}}\
th:first-child,td:first-child{{text-align:left;white-space:normal}}figure{{margin:1.5em 0}}figure svg{{max-width:100%;height:auto}}code{{background:#f4f4f4;padding:0 3px}}\
.note{{color:#555;font-size:90%}}</style></head><body>\n",
        name = esc(&s.name)
    );
    let seeds = rows.first().map_or(&[][..], |r| &r.seeds[..]);
    let seed_text = match (seeds.first(), seeds.last()) {
        (Some(a), Some(b)) if a != b => format!("seeds {a}–{b} ({} runs per case)", seeds.len()),
        (Some(a), _) => format!("seed {a}"),
        _ => "no seed".to_string(),
    };
    let _ = write!(
        o,
        "<h1>Position synchronisation on a ring network: Table 1 of Huang et al. (2015), simulated</h1>\n\
<p>The paper proposes a cycle that combines one <em>lumped</em> frame (clock sync and every axis's feedback from the same \
instant) with <em>point-to-point</em> time slices (one acknowledged command per axis, with reserved slices for retries), and \
a position-synchronisation controller that couples every axis to the mean of all others (ε = T·e) with a motion message \
estimator that compensates the known network delays. It reports, on four servo axes at 1 ms, that the controller lowers the \
synchronisation error (Sync-RMSE) by 49.270 % and the tracking error (Track-RMSE) by 21.171 % against standard PD.</p>\n\
<p>This page is ringsync's reproduction in its deterministic co-simulator: the same frames on modelled 100 Mbit/s links, \
drifting clocks synchronised from the frames, the sans-IO master and slaves that the real runtime is built to run as well, and simulated \
servo axes. Scenario <code>{name}</code>, {seed_text}, {n} axes, {dur} s, T<sub>cyc</sub> = {cyc} ms, estimator \
<code>{est}</code>. Each seed draws other oscillators, jitter and losses; the paper reports one experiment per case, \
ringsync the mean, the spread and the range over the seeds. Re-run it with <code>cargo run --release -p ringsync-cli -- reproduce --seeds {nseeds}</code>.</p>\n",
        name = esc(&s.name),
        n = s.axes_count(),
        dur = s.duration.secs(),
        cyc = s.ring.cycle.secs() * 1e3,
        est = s.control.estimator.name(),
        nseeds = seeds.len(),
    );
    o.push_str("<h2>Table 1 [rad]</h2>\n");
    o.push_str(&markdown_html(&repro_table(rows, bench)));
    let _ = writeln!(
        o,
        "<p class=\"note\">Track-RMSE = sqrt((1/N)·Σ<sub>j</sub>Σ<sub>i</sub> e<sub>i</sub>(j)²), Sync-RMSE likewise with ε (eq. 26-27), \
one sample per cycle, the sum over the axes inside the root. In the lumped-only plan the slaves run the law themselves \
on what the frame carries: this cycle's data of the slaves before them, last cycle's of those after.</p>"
    );
    let _ = writeln!(
        o,
        "<h2>Figures</h2>\n<p class=\"note\">The runs of the first seed ({}).</p>",
        seeds.first().map_or("–".to_string(), u64::to_string)
    );
    for (name, svg) in figures {
        let body = svg.split_once("?>\n").map_or(svg.as_str(), |(_, b)| b);
        let _ = writeln!(
            o,
            "<figure>{body}<figcaption class=\"note\">{name}</figcaption></figure>"
        );
    }
    let _ = write!(
        o,
        "<h2>What the paper does not report: the assumptions</h2>\n<p>The reference scenario fills the gaps as follows (docs/system.md, \"The reference scenario\"; <code>ringsync scenario show {}</code> prints every value):</p><ul>\n",
        esc(&s.name)
    );
    let axes: Vec<String> = s
        .axis
        .iter()
        .map(|a| {
            format!(
                "rated torque {} N·m, J/K<sub>a</sub> = {} s²·V/rad, b = {} N·m·s/rad",
                a.rated_torque, a.j_over_ka, a.viscous
            )
        })
        .collect();
    for item in [
        format!("Axes: voltage-commanded torque-mode drives, ±{} V = ± rated torque: {}.", s.axis[0].u_max, axes.join("; ")),
        format!(
            "Coulomb friction {} % of rated torque ({} sign); encoders 2<sup>{}</sup> counts per revolution; velocity by encoder difference over {} µs.",
            s.axis[0].coulomb_fraction * 100.0,
            if matches!(s.axis[0].coulomb_sign, CoulombSign::Exact) { "exact sign with stiction, the v<sub>s</sub> → 0 limit of the spec's tanh" } else { "tanh" },
            s.axis[0].encoder_bits,
            s.axis[0].velocity_window.secs() * 1e6
        ),
        "Command: x<sup>d</sup> = A·(1 − cos(2πt/P)) on every axis, P = 2 s, peak speed 15.12 rad/s.".to_string(),
        format!(
            "Gains: K<sub>P</sub> = 3.182 V/rad, K<sub>D</sub> = 1.591 V·s/rad for both controllers; the sync controller adds α = {}, K<sub>E</sub> = 0.75 V·s/rad; K<sub>H</sub> = K<sub>C</sub> = 0, K<sub>N</sub> = 0.",
            s.control.alpha
        ),
        format!(
            "Network: {} Mbit/s, PHY latencies {} / {} ns, {} m cables, residence {} µs, response delay {} µs, T<sub>rest</sub> {} µs; slave oscillators within ±{} ppm, timestamps at {} ns; encoders latched {}.",
            s.ring.bit_rate.0 / 1_000_000,
            s.ring.phy_rx.0.as_ns(),
            s.ring.phy_tx.0.as_ns(),
            s.ring.cable_m,
            s.ring.residence.0.as_ns() as f64 / 1e3,
            s.ring.response_delay.0.as_ns() as f64 / 1e3,
            s.ring.t_rest.0.as_ns() as f64 / 1e3,
            s.clock.drift_ppm,
            s.clock.timestamp_resolution.0.as_ns(),
            match s.clock.sample_lead.0.as_ns() {
                0 => "at each cycle start".to_string(),
                lead => format!("{} µs before each cycle start", lead as f64 / 1e3),
            }
        ),
    ] {
        let _ = writeln!(o, "<li>{item}</li>");
    }
    for a in ASSUMPTIONS
        .iter()
        .chain(&[P2P_ASSUMPTION, LUMPED_ONLY_ASSUMPTION])
        .chain(ringsync_proto::plan::ASSUMPTIONS)
    {
        let _ = writeln!(o, "<li>{}</li>", esc(a));
    }
    let _ = write!(
        o,
        "</ul>\n<p class=\"note\">Generated by ringsync. Deterministic: the same scenario and seed give the same page.</p>\n</body></html>\n"
    );
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(plan: &'static str, controller: &'static str, t: &[f64], s: &[f64]) -> ReproRow {
        ReproRow {
            plan,
            controller,
            seeds: (1..=t.len() as u64).collect(),
            track_rmse: t.to_vec(),
            sync_rmse: s.to_vec(),
        }
    }

    #[test]
    fn reductions_are_paired_by_seed() {
        let rows = [
            row("p2p-lumped", "pd", &[0.2, 0.4], &[0.004, 0.002]),
            row("p2p-lumped", "sync", &[0.15, 0.2], &[0.002, 0.001]),
        ];
        let r = reductions(&rows);
        assert_eq!(r.len(), 2, "no lumped-only rows, no lumped-only reductions");
        // Track: seed 1 25 %, seed 2 50 % (paired); unpaired means would give 41.7 %.
        assert!((r[0].ours.mean - 37.5).abs() < 1e-12, "{:?}", r[0]);
        assert!((r[0].ours.min - 25.0).abs() < 1e-12 && (r[0].ours.max - 50.0).abs() < 1e-12);
        assert!((r[1].ours.mean - 50.0).abs() < 1e-12 && r[1].ours.sd.abs() < 1e-12);
        assert_eq!((r[0].paper, r[1].paper), (21.171, 49.270));
    }

    #[test]
    fn the_verdict_says_where_the_paper_lies() {
        let rows = [
            row("p2p-lumped", "pd", &[0.2, 0.2], &[0.004, 0.004]),
            row("p2p-lumped", "sync", &[0.15, 0.16], &[0.0021, 0.0019]),
        ];
        let c = claims(&rows, None);
        assert_eq!(c.len(), 2, "no lumped-only rows: claim 1 only");
        // Sync: 47.5-52.5 % covers 49.270 %; Track: 20-25 % covers 21.171 %.
        assert_eq!(
            (c[0].metric.as_str(), c[0].verdict),
            ("Sync-RMSE", ClaimVerdict::Reproduced)
        );
        assert_eq!(
            (c[1].metric.as_str(), c[1].verdict),
            ("Track-RMSE", ClaimVerdict::Reproduced)
        );
        let v = verdict(&rows, None);
        assert!(
            v[1].contains("lies within our range (20.0–25.0 %), 1.3 points below our mean"),
            "{v:?}"
        );
        assert!(
            v[0].contains("within our range") && v[0].contains("points"),
            "{v:?}"
        );
        let rows = [
            row("p2p-lumped", "pd", &[0.2, 0.2], &[0.004, 0.004]),
            row("p2p-lumped", "sync", &[0.21, 0.22], &[0.003, 0.0031]),
        ];
        let c = claims(&rows, None);
        assert_eq!(c[0].verdict, ClaimVerdict::DirectionOnly, "{c:?}");
        assert_eq!(c[1].verdict, ClaimVerdict::NotReproduced, "{c:?}");
        let v = verdict(&rows, None);
        assert!(
            v[0].contains("lies above our range")
                && v[0].contains("direction reproduced, size not"),
            "{v:?}"
        );
        let t = repro_table(&rows, None);
        assert!(
            t.contains(
                "| Sync-RMSE, sync controller vs standard PD, proposed (P2P + lumped) | 49.270 % |"
            ),
            "{t}"
        );
        assert!(t.contains("0.20000 ± 0.00000"), "{t}");
    }

    #[test]
    fn the_plan_claim_compares_each_seed_on_both_plans() {
        let rows = [
            row("p2p-lumped", "pd", &[0.2, 0.2], &[0.004, 0.004]),
            row("p2p-lumped", "sync", &[0.15, 0.16], &[0.0020, 0.0022]),
            row("lumped-only", "pd", &[0.2, 0.2], &[0.004, 0.004]),
            row("lumped-only", "sync", &[0.15, 0.16], &[0.0025, 0.0021]),
        ];
        let g = plan_gaps(&rows);
        // Seed 1: 1 − 0.0020/0.0025 = 20 %; seed 2: 1 − 0.0022/0.0021 < 0.
        let sync = g.iter().find(|g| g.controller == "sync").expect("sync");
        assert!(
            (sync.ours.max - 20.0).abs() < 1e-9 && sync.ours.min < 0.0,
            "{sync:?}"
        );
        assert!((sync.paper - 37.996).abs() < 1e-3, "{}", sync.paper);
        let c = claims(&rows, None);
        let plan = c.iter().find(|c| c.claim == "plan").expect("plan claim");
        assert_eq!(plan.verdict, ClaimVerdict::NotReproduced);
        assert!(
            plan.text.contains("PD rows differ by 33.7 %"),
            "{}",
            plan.text
        );
        let bench = BenchRows {
            spread: 1.5,
            pd: row("lumped-only", "pd", &[0.2, 0.2], &[0.006, 0.006]),
            sync: row("lumped-only", "sync", &[0.15, 0.16], &[0.0033, 0.0033]),
        };
        let j = repro_json("x", &rows, Some(&bench));
        assert!(
            (j["bench"]["pd_ratio"].as_f64().expect("ratio") - 1.5).abs() < 1e-12,
            "{j}"
        );
        assert!(
            (j["bench"]["reduction_percent"]["mean"]
                .as_f64()
                .expect("red")
                - 45.0)
                .abs()
                < 1e-9
        );
        assert_eq!(j["claims"][2]["verdict"], "not-reproduced");
        let t = repro_table(&rows, Some(&bench));
        assert!(
            t.contains("| lumped-only, J/K_a spread 1.5× (bench experiment) | standard PD |"),
            "{t}"
        );
        assert!(
            t.contains("spread 1.5× wider raises our standard PD's Sync-RMSE 1.50×"),
            "{t}"
        );
    }

    #[test]
    fn one_seed_has_no_spread_and_the_json_keeps_every_seed() {
        let rows = [row("lumped-only", "ring-coupled", &[0.3], &[0.005])];
        let j = repro_json("x", &rows, None);
        assert_eq!(j["cases"][0]["seeds"], 1);
        assert_eq!(j["cases"][0]["track_rmse_sd"], 0.0);
        assert_eq!(j["cases"][0]["sync_rmse_per_seed"][0], 0.005);
        assert_eq!(
            j["cases"][0]["paper_sync_rmse"],
            Value::Null,
            "no paper value"
        );
        assert_eq!(j["schema_version"], REPRO_SCHEMA_VERSION);
        let html = markdown_html(&repro_table(&rows, None));
        assert!(
            html.contains("<th>plan</th>") && html.contains("<li>"),
            "{html}"
        );
        assert_eq!(
            html.matches("<table>").count(),
            html.matches("</table>").count()
        );
    }
}
