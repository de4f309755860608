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
//!   rayon. Scopes nest by stack discipline, so a rayon worker that steals another job while it
//!   waits records that job's stages in that job's own scope, and the stolen job's time still
//!   counts in the waiting stage's wall time. `--profile` runs assets one at a time, so an
//!   asset's figures hold no other asset's work; the representations of one asset run
//!   concurrently, so their stages overlap and the rows of one asset may add up to more than
//!   its wall time;
//! - a scope may be opened more than once for the same asset and representation (the pipeline
//!   builds, then measures): the table adds its totals into one row;
//! - per asset, [`Profile::asset`] records the wall time from the start of loading its mesh or
//!   texture to its last file committed (**mesh to files**: what a renderer needs; measure and
//!   report excluded) and to its end ([`AssetTime`]).

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

/// Wall-clock times of one asset as a whole (see [`Profile::asset`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AssetTime {
    /// Asset name.
    pub asset: String,
    /// Seconds to read and prepare its mesh, shape or texture (a mesh's BVH excluded).
    pub load_seconds: f64,
    /// Seconds its geometry took to prepare ray queries (a mesh's BVH build), after the load,
    /// while the representations that cast no rays were already building; `None` when none of
    /// its representations casts rays (nothing prepared) or it has no geometry.
    pub rays_seconds: Option<f64>,
    /// Seconds from the start of loading to its last representation's files committed: the
    /// precompute itself, measure and report excluded.
    pub files_seconds: f64,
    /// Seconds from the start of loading to the end of its last report.
    pub total_seconds: f64,
}

#[derive(Debug, Default)]
struct Sink {
    stages: Vec<StageTime>,
    totals: Vec<(String, String, f64)>,
    declared: Vec<(String, String)>,
    assets: Vec<AssetTime>,
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

    /// Declares the row of `asset` / `representation`, so that the table lists rows in
    /// declaration order whatever order concurrent scopes end in (undeclared rows follow, in the
    /// order their first scope ended).
    pub fn declare(&self, asset: &str, representation: &str) {
        if let Ok(mut s) = self.sink.lock() {
            let key = (asset.to_string(), representation.to_string());
            if !s.declared.contains(&key) {
                s.declared.push(key);
            }
        }
    }

    /// Records the wall times of `asset` as a whole (see [`AssetTime`]).
    pub fn asset(&self, time: AssetTime) {
        if let Ok(mut s) = self.sink.lock() {
            s.assets.push(time);
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
        let Ok(s) = self.sink.lock() else {
            return StageTable::new(&[], &[], &[], Vec::new(), wall_seconds);
        };
        StageTable::new(
            &s.stages,
            &s.totals,
            &s.declared,
            s.assets.clone(),
            wall_seconds,
        )
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
    /// Wall seconds of the whole representation (plan to report, cache checks included; the
    /// sum over its scopes).
    pub total_seconds: f64,
    /// `total − Σ stages`: time no stage claims (≥ 0 up to clock rounding).
    pub other_seconds: f64,
}

/// Stage times of a run: one row per representation of each asset, plus per-stage sums.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageTable {
    /// Stage names present, in [`STAGES`] order.
    pub stage_names: Vec<String>,
    /// One row per representation of each asset, in declaration order
    /// ([`Profile::declare`]), then in completion order.
    pub rows: Vec<StageRow>,
    /// Per asset, its wall times as a whole, in recording order.
    pub assets: Vec<AssetTime>,
    /// Per stage, the sum over every row.
    pub stage_sums: BTreeMap<String, f64>,
    /// Sum of the rows' totals.
    pub total_seconds: f64,
    /// Wall seconds of the whole run (loading, reports and pictures included).
    pub wall_seconds: f64,
}

impl StageTable {
    fn new(
        stages: &[StageTime],
        totals: &[(String, String, f64)],
        declared: &[(String, String)],
        assets: Vec<AssetTime>,
        wall_seconds: f64,
    ) -> Self {
        let order = |s: &str| STAGES.iter().position(|n| *n == s).unwrap_or(STAGES.len());
        let mut names: Vec<String> = Vec::new();
        for s in stages {
            if !names.iter().any(|n| n == s.stage) {
                names.push(s.stage.to_string());
            }
        }
        names.sort_by_key(|n| order(n));
        // One total per row: declared rows first, then the rest by first completion.
        let mut keyed: Vec<(String, String, f64)> = declared
            .iter()
            .filter(|(a, r)| totals.iter().any(|t| &t.0 == a && &t.1 == r))
            .map(|(a, r)| (a.clone(), r.clone(), 0.0))
            .collect();
        for (asset, repr, total) in totals {
            match keyed.iter_mut().find(|k| &k.0 == asset && &k.1 == repr) {
                Some(k) => k.2 += total,
                None => keyed.push((asset.clone(), repr.clone(), *total)),
            }
        }
        let rows: Vec<StageRow> = keyed
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
            assets,
            stage_sums,
            wall_seconds,
        }
    }

    /// The table in Markdown: milliseconds per stage, one row per representation of each asset,
    /// then the sums; then, when recorded, the per-asset table (load, mesh to files, total).
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
            " {:.1} | {:.1} |\n\nMilliseconds, wall clock; run wall time {:.1} ms. Assets run one at a \
             time; the representations of an asset run concurrently, so their rows overlap.\n",
            (self.total_seconds - claimed) * 1e3,
            self.total_seconds * 1e3,
            self.wall_seconds * 1e3
        );
        if !self.assets.is_empty() {
            s += "\n| asset | load | ray set-up | mesh to files | total |\n|---|---|---|---|---|\n";
            for a in &self.assets {
                s += &format!(
                    "| {} | {:.1} | {} | {:.1} | {:.1} |\n",
                    a.asset,
                    a.load_seconds * 1e3,
                    ms(a.rays_seconds.as_ref()),
                    a.files_seconds * 1e3,
                    a.total_seconds * 1e3
                );
            }
            s += "\nMilliseconds, wall clock. Load: reading and parsing; ray set-up: a mesh's BVH \
                  build, after the load, while the representations that cast no rays (octree, \
                  pyramid) already build; mesh to files: from the start of loading to the asset's \
                  last file committed (measure and report excluded); total: to the end of its last \
                  report.\n";
        }
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

    #[test]
    fn scopes_of_one_row_add_up_and_declared_rows_come_first() {
        let p = Profile::new();
        p.declare("a", "parallax");
        p.declare("a", "octree");
        for _ in 0..2 {
            let _s = p.scope("a", "octree");
            stage("octree", || {
                std::thread::sleep(std::time::Duration::from_millis(1))
            });
        }
        {
            let _s = p.scope("b", "cylinder");
        }
        {
            let _s = p.scope("a", "parallax");
        }
        p.asset(super::AssetTime {
            asset: "a".into(),
            load_seconds: 0.001,
            rays_seconds: Some(0.0015),
            files_seconds: 0.002,
            total_seconds: 0.003,
        });
        p.asset(super::AssetTime {
            asset: "b".into(),
            load_seconds: 0.004,
            rays_seconds: None,
            files_seconds: 0.005,
            total_seconds: 0.006,
        });
        let t = p.table(1.0);
        let rows: Vec<(&str, &str)> = t
            .rows
            .iter()
            .map(|r| (r.asset.as_str(), r.representation.as_str()))
            .collect();
        assert_eq!(
            rows,
            [("a", "parallax"), ("a", "octree"), ("b", "cylinder")]
        );
        let octree = &t.rows[1];
        assert!(octree.stages["octree"] >= 0.002);
        assert!(octree.total_seconds >= octree.stages["octree"]);
        let md = t.markdown();
        assert!(md.contains("| a | 1.0 | 1.5 | 2.0 | 3.0 |"), "{md}");
        assert!(md.contains("| b | 4.0 | – | 5.0 | 6.0 |"), "{md}");
    }
}
