//! # Per-stage timing of the precompute pipeline (`altrep precompute --profile`)
//!
//! A [`Profile`] collects wall-clock times of named **stages** (capture, bounds, octree, writing,
//! …) per asset and representation. The pipeline opens a [`Scope`] for each representation it
//! builds; code anywhere below it on the same thread wraps a stage in [`stage`]. Outside a scope
//! [`stage`] only calls its closure (one thread-local read: no measurable overhead), so the
//! builders need no extra parameter and behave identically with and without `--profile`.
//!
//! Rules that keep the table honest:
//! - stages are **not nested**: the stages of one scope never overlap, so they add up to at most
//!   the scope's total, and the rest ([`StageTable::rows`]' `other`) is the time no stage claims
//!   (planning, cache checks, setup between stages);
//! - a stage is timed on the thread that opened the scope; the work inside may fan out over
//!   rayon. Scopes nest by stack discipline, so a rayon worker that steals another asset's job
//!   while it waits records that job's stages in that asset's scope (its time still counts in the
//!   outer stage's wall time: per-stage figures are only clean when assets run one at a time,
//!   which `--profile` does).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use serde::Serialize;

/// One timed stage of one representation of one asset.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageTime {
    /// Asset name.
    pub asset: String,
    /// Representation name (`parallax`, `cylinder`, `octree`, `pyramid`).
    pub representation: String,
    /// Stage name (see [`STAGES`]).
    pub stage: &'static str,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// The stage names the pipeline uses, in pipeline order (tables list them in this order; a stage
/// not listed here goes after them).
pub const STAGES: [&str; 13] = [
    "plan",
    "capture",
    "sampling",
    "assembly",
    "solve",
    "quantisation",
    "bounds",
    "voxelise",
    "octree",
    "pyramids",
    "writing",
    "measure",
    "report",
];

#[derive(Debug, Default)]
struct Sink {
    stages: Vec<StageTime>,
    totals: Vec<(String, String, f64)>,
}

/// A thread-safe collector of stage times. Cheap to share: clone the [`Arc`] it lives in.
#[derive(Debug, Default)]
pub struct Profile {
    sink: Mutex<Sink>,
}

#[derive(Clone)]
struct Context {
    profile: Arc<Profile>,
    asset: String,
    representation: String,
}

thread_local! {
    static CONTEXT: RefCell<Vec<Context>> = const { RefCell::new(Vec::new()) };
}

/// While alive, [`stage`] calls on this thread record into its profile under its asset and
/// representation. Dropping it records the scope's total and restores the previous scope.
pub struct Scope {
    start: Instant,
    context: Context,
}

impl Profile {
    /// An empty profile, ready to share.
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// Opens a scope for `asset` / `representation` on this thread (see [`Scope`]).
    pub fn scope(self: &Arc<Self>, asset: &str, representation: &str) -> Scope {
        let context = Context {
            profile: Arc::clone(self),
            asset: asset.to_string(),
            representation: representation.to_string(),
        };
        CONTEXT.with(|c| c.borrow_mut().push(context.clone()));
        Scope {
            start: Instant::now(),
            context,
        }
    }

    fn record(&self, t: StageTime) {
        if let Ok(mut s) = self.sink.lock() {
            s.stages.push(t);
        }
    }

    /// Every stage recorded so far, in recording order.
    pub fn stages(&self) -> Vec<StageTime> {
        self.sink
            .lock()
            .map(|s| s.stages.clone())
            .unwrap_or_default()
    }

    /// The table of stages per asset and representation (see [`StageTable`]), with the run's
    /// wall time `wall_seconds`.
    pub fn table(&self, wall_seconds: f64) -> StageTable {
        let (stages, totals) = self
            .sink
            .lock()
            .map(|s| (s.stages.clone(), s.totals.clone()))
            .unwrap_or_default();
        StageTable::new(&stages, &totals, wall_seconds)
    }
}

impl Drop for Scope {
    fn drop(&mut self) {
        let seconds = self.start.elapsed().as_secs_f64();
        CONTEXT.with(|c| {
            c.borrow_mut().pop();
        });
        if let Ok(mut s) = self.context.profile.sink.lock() {
            s.totals.push((
                self.context.asset.clone(),
                self.context.representation.clone(),
                seconds,
            ));
        }
    }
}

/// Runs `f` as stage `name` of the innermost open [`Scope`] on this thread, recording its wall
/// time; without a scope it only runs `f`. Stages must not nest (module docs).
pub fn stage<T>(name: &'static str, f: impl FnOnce() -> T) -> T {
    let context = CONTEXT.with(|c| c.borrow().last().cloned());
    let Some(context) = context else {
        return f();
    };
    let t0 = Instant::now();
    let out = f();
    context.profile.record(StageTime {
        asset: context.asset,
        representation: context.representation,
        stage: name,
        seconds: t0.elapsed().as_secs_f64(),
    });
    out
}

/// A running stage timer ([`timer`]): records its stage when stopped or dropped.
#[must_use = "a timer records when it is stopped or dropped"]
pub struct StageTimer {
    name: &'static str,
    start: Instant,
    context: Option<Context>,
}

/// Starts stage `name` of the innermost open [`Scope`] on this thread; it ends when the returned
/// timer is stopped ([`StageTimer::stop`]) or dropped. The form to use where wrapping the stage
/// in a closure ([`stage`]) is awkward (`?` inside, many bindings out). Without a scope it
/// records nothing.
pub fn timer(name: &'static str) -> StageTimer {
    StageTimer {
        name,
        start: Instant::now(),
        context: CONTEXT.with(|c| c.borrow().last().cloned()),
    }
}

impl StageTimer {
    /// Ends the stage now.
    pub fn stop(self) {}
}

impl Drop for StageTimer {
    fn drop(&mut self) {
        if let Some(c) = self.context.take() {
            c.profile.record(StageTime {
                asset: c.asset,
                representation: c.representation,
                stage: self.name,
                seconds: self.start.elapsed().as_secs_f64(),
            });
        }
    }
}

/// One row of a [`StageTable`]: one representation of one asset.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageRow {
    /// Asset name.
    pub asset: String,
    /// Representation name.
    pub representation: String,
    /// Seconds per stage (stages that did not run are absent).
    pub stages: BTreeMap<String, f64>,
    /// Wall seconds of the whole representation (plan to report, cache checks included).
    pub total_seconds: f64,
    /// `total − Σ stages`: time no stage claims (≥ 0 up to clock rounding).
    pub other_seconds: f64,
}

/// Stage times of a run: one row per representation of each asset, plus per-stage sums.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageTable {
    /// Stage names present, in [`STAGES`] order.
    pub stage_names: Vec<String>,
    /// One row per representation of each asset, in completion order.
    pub rows: Vec<StageRow>,
    /// Per stage, the sum over every row.
    pub stage_sums: BTreeMap<String, f64>,
    /// Sum of the rows' totals.
    pub total_seconds: f64,
    /// Wall seconds of the whole run (loading, reports and pictures included).
    pub wall_seconds: f64,
}

impl StageTable {
    fn new(stages: &[StageTime], totals: &[(String, String, f64)], wall_seconds: f64) -> Self {
        let order = |s: &str| STAGES.iter().position(|n| *n == s).unwrap_or(STAGES.len());
        let mut names: Vec<String> = Vec::new();
        for s in stages {
            if !names.iter().any(|n| n == s.stage) {
                names.push(s.stage.to_string());
            }
        }
        names.sort_by_key(|n| order(n));
        let rows: Vec<StageRow> = totals
            .iter()
            .map(|(asset, repr, total)| {
                let mut map = BTreeMap::new();
                for s in stages
                    .iter()
                    .filter(|s| &s.asset == asset && &s.representation == repr)
                {
                    *map.entry(s.stage.to_string()).or_insert(0.0) += s.seconds;
                }
                let claimed: f64 = map.values().sum();
                StageRow {
                    asset: asset.clone(),
                    representation: repr.clone(),
                    stages: map,
                    total_seconds: *total,
                    other_seconds: total - claimed,
                }
            })
            .collect();
        let mut stage_sums = BTreeMap::new();
        for r in &rows {
            for (k, v) in &r.stages {
                *stage_sums.entry(k.clone()).or_insert(0.0) += v;
            }
        }
        Self {
            stage_names: names,
            total_seconds: rows.iter().map(|r| r.total_seconds).sum(),
            rows,
            stage_sums,
            wall_seconds,
        }
    }

    /// The table in Markdown: milliseconds per stage, one row per representation of each asset,
    /// then the sums.
    pub fn markdown(&self) -> String {
        let mut s = String::from("| asset | representation |");
        for n in &self.stage_names {
            s += &format!(" {n} |");
        }
        s += " other | total |\n|---|---|";
        s += &"---|".repeat(self.stage_names.len() + 2);
        s += "\n";
        let ms = |v: Option<&f64>| v.map_or("–".to_string(), |v| format!("{:.1}", v * 1e3));
        for r in &self.rows {
            s += &format!("| {} | {} |", r.asset, r.representation);
            for n in &self.stage_names {
                s += &format!(" {} |", ms(r.stages.get(n)));
            }
            s += &format!(
                " {:.1} | {:.1} |\n",
                r.other_seconds * 1e3,
                r.total_seconds * 1e3
            );
        }
        s += "| **all** | |";
        for n in &self.stage_names {
            s += &format!(" {} |", ms(self.stage_sums.get(n)));
        }
        let claimed: f64 = self.stage_sums.values().sum();
        s += &format!(
            " {:.1} | {:.1} |\n\nMilliseconds, wall clock; run wall time {:.1} ms (assets one at a time).\n",
            (self.total_seconds - claimed) * 1e3,
            self.total_seconds * 1e3,
            self.wall_seconds * 1e3
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::{Profile, stage};

    #[test]
    fn stages_outside_a_scope_are_not_recorded_and_inside_add_up_to_at_most_the_total() {
        let p = Profile::new();
        assert_eq!(stage("capture", || 3), 3);
        {
            let _s = p.scope("a", "parallax");
            stage("capture", || {
                std::thread::sleep(std::time::Duration::from_millis(2))
            });
            stage("bounds", || ());
            {
                let _inner = p.scope("b", "octree");
                stage("octree", || ());
            }
            let t = super::timer("bounds");
            t.stop();
        }
        let t = p.table(1.0);
        assert_eq!(t.rows.len(), 2);
        let a = t.rows.iter().find(|r| r.asset == "a").unwrap();
        assert_eq!(a.stages.len(), 2);
        assert!(a.stages["capture"] >= 0.002);
        assert!(a.other_seconds >= 0.0);
        let b = t.rows.iter().find(|r| r.asset == "b").unwrap();
        assert_eq!(b.stages.keys().collect::<Vec<_>>(), ["octree"]);
        assert_eq!(t.stage_names, ["capture", "bounds", "octree"]);
        assert!(t.markdown().contains("| a | parallax |"));
    }
}
