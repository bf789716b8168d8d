//! The corpus file (`datasets/corpus.toml`): its groups expanded into cases.

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The corpus format this build reads.
pub const CORPUS_FORMAT: u32 = 1;

/// The most cases a corpus may expand to.
pub const MAX_CASES: usize = 10_000;

/// What a case exercises.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Camera datasets: profiles, turns, maps.
    Camera,
    /// Real camera recordings with motion capture: turns and trajectory.
    Real,
    /// Place index and queries.
    Places,
    /// Laser logs.
    Laser,
    /// Pose graphs.
    Graph,
}

impl Kind {
    /// Every kind, in the order the scoreboard shows them.
    pub const ALL: [Kind; 5] = [Kind::Camera, Kind::Real, Kind::Places, Kind::Laser, Kind::Graph];

    /// The kind's name in the corpus and the scoreboard.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Camera => "camera",
            Kind::Real => "real",
            Kind::Places => "places",
            Kind::Laser => "laser",
            Kind::Graph => "graph",
        }
    }
}

/// A target on one figure: at most `max`, at least `min`; `gate` makes
/// `eval suite --check` fail on it (CI's quality gate).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bound {
    /// The least value that meets the target.
    pub min: Option<f64>,
    /// The largest value that meets the target.
    pub max: Option<f64>,
    /// `true`: a case short of the target fails `--check`; `{ max = X }`
    /// or `{ min = X }`: a case beyond that limit does (a floor under a
    /// target some cases do not meet yet).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gate: Option<Gate>,
}

/// How a target gates `eval suite --check`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Gate {
    /// `gate = true`: the target is the gate; `false`: no gate.
    Target(bool),
    /// `gate = { max = X }`: a limit of its own.
    Limit {
        /// The least value that passes.
        #[serde(default)]
        min: Option<f64>,
        /// The largest value that passes.
        #[serde(default)]
        max: Option<f64>,
    },
}

impl Bound {
    /// Whether `value` meets the target.
    pub fn holds(&self, value: f64) -> bool {
        within(self.min, self.max, value)
    }

    /// Whether `value` (`None`: the figure is missing) fails the gate;
    /// never without one.
    pub fn gate_fails(&self, value: Option<f64>) -> bool {
        match self.gate {
            None | Some(Gate::Target(false)) => false,
            Some(Gate::Target(true)) => !value.is_some_and(|v| self.holds(v)),
            Some(Gate::Limit { min, max }) => !value.is_some_and(|v| within(min, max, v)),
        }
    }

    /// The gate as text, if any: `≤ 0.06`.
    pub fn gate_text(&self) -> Option<String> {
        match self.gate {
            None | Some(Gate::Target(false)) => None,
            Some(Gate::Target(true)) => Some(self.text()),
            Some(Gate::Limit { min, max }) => Some(range_text(min, max)),
        }
    }

    /// The target as text: `≤ 0.02`, `≥ 0.9`.
    pub fn text(&self) -> String {
        range_text(self.min, self.max)
    }

    fn check(&self, figure: &str) -> Result<()> {
        let finite = |v: Option<f64>| v.is_none_or(f64::is_finite);
        if self.min.is_none() && self.max.is_none() {
            bail!("target {figure}: give `min` or `max`");
        }
        if !finite(self.min) || !finite(self.max) {
            bail!("target {figure}: limits must be finite numbers");
        }
        if let Some(Gate::Limit { min, max }) = self.gate {
            if (min.is_none() && max.is_none()) || !finite(min) || !finite(max) {
                bail!("target {figure}: a gate's `min` or `max` must be a finite number");
            }
            // A gate looser than the target, in the target's direction.
            let looser = min.is_none_or(|g| self.min.is_some_and(|t| g <= t))
                && max.is_none_or(|g| self.max.is_some_and(|t| g >= t));
            if !looser {
                bail!("target {figure}: its gate must be looser than the target, on the same side");
            }
        }
        Ok(())
    }
}

fn within(min: Option<f64>, max: Option<f64>, value: f64) -> bool {
    min.is_none_or(|m| value >= m) && max.is_none_or(|m| value <= m)
}

fn range_text(min: Option<f64>, max: Option<f64>) -> String {
    match (min, max) {
        (Some(lo), Some(hi)) => format!("{lo}-{hi}"),
        (Some(lo), None) => format!("≥ {lo}"),
        (None, Some(hi)) => format!("≤ {hi}"),
        (None, None) => "-".into(),
    }
}

/// The figures a camera case gives.
const CAMERA_FIGURES: &[&str] = &[
    "missed",
    "false_range",
    "wrong_verified",
    "max_verified_error_deg",
    "ate_aligned_m",
    "f1",
];
/// A real recording's: its trajectory against the motion capture, on the
/// clock found from the images.
const REAL_FIGURES: &[&str] = &[
    "ate_aligned_m",
    "heading_rmse_deg",
    "turn_error_median_deg",
    "turn_error_p95_deg",
    "heading_after_full_turn_deg",
    "profile_agreement",
];
/// A places case's figures; the first three are given whatever the
/// answers (the rest need an answer, or a right one).
const PLACES_FIGURES: &[&str] = &[
    "recall_at_1",
    "far_wrong",
    "answers",
    "precision",
    "pose_error_max_deg",
    "pose_error_max_m",
];
/// A laser log's, as recorded; a variant adds `rpe_1m_vs_odometry`.
const LASER_FIGURES: &[&str] = &[
    "ate_m",
    "rpe_1m_m",
    "rpe_1m_deg",
    "wrong_unmarked_share",
    "rpe_1m_vs_odometry",
];
/// A benchmark bag's.
const BAG_FIGURES: &[&str] = &[
    "relations_trans_m",
    "relations_rot_deg",
    "relations_unmatched",
    "relations_trans_vs_cartographer",
    "relations_rot_vs_cartographer",
    "time_vs_cartographer",
];
/// A pose graph's as published or perturbed ...
const GRAPH_FIGURES: &[&str] = &["chi2_final", "iterations", "chi2_vs_reference"];
/// ... and with outliers.
const OUTLIER_GRAPH_FIGURES: &[&str] = &["chi2_final", "iterations", "inlier_chi2_vs_reference"];

impl Kind {
    /// Every figure a case of this kind can give (docs/scoreboard.md).
    pub fn figures(self) -> Vec<&'static str> {
        match self {
            Kind::Camera => CAMERA_FIGURES.to_vec(),
            Kind::Real => REAL_FIGURES.to_vec(),
            Kind::Places => PLACES_FIGURES.to_vec(),
            Kind::Laser => [LASER_FIGURES, BAG_FIGURES].concat(),
            Kind::Graph => [GRAPH_FIGURES, &OUTLIER_GRAPH_FIGURES[2..]].concat(),
        }
    }
}

/// Where a camera dataset comes from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Source {
    /// `$PIROUETTE_SHARED/datasets/NAME`.
    Shared(String),
    /// A render of a scene (built-in name or file beside the corpus) with
    /// a patch merged into it.
    Render {
        /// Built-in scene name or file name.
        scene: String,
        /// The seed.
        seed: u64,
        /// Merged into the scene's JSON before rendering.
        patch: Option<serde_json::Value>,
        /// The name the case shows (the group's or the scene's).
        label: String,
    },
}

impl Source {
    /// The name shown in case ids.
    pub fn label(&self) -> String {
        match self {
            Source::Shared(name) => name.clone(),
            Source::Render { label, seed, .. } => format!("{label} seed {seed}"),
        }
    }
}

/// A laser log as recorded or changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum LaserVariant {
    /// The log as it is.
    AsRecorded,
    /// Every `keep`-th scan, the odometry composed over the scans left
    /// out, or dropped.
    Every {
        /// Scans kept: one in `keep`.
        keep: usize,
        /// Whether the odometry stays.
        odometry: bool,
    },
    /// The odometry dropped.
    NoOdometry,
    /// Every odometry step scaled by 5 % and turned by 2° (σ), seeded.
    NoisyOdometry,
}

impl LaserVariant {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "as-recorded" => Self::AsRecorded,
            "no-odometry" => Self::NoOdometry,
            "noisy-odometry" => Self::NoisyOdometry,
            _ => {
                let rest = s.strip_prefix("every-")?;
                let (n, odometry) = match rest.strip_suffix("-no-odometry") {
                    Some(n) => (n, false),
                    None => (rest, true),
                };
                let keep: usize = n.parse().ok().filter(|k| (2..=100).contains(k))?;
                Self::Every { keep, odometry }
            }
        })
    }
}

/// A pose graph as published or made harder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum GraphVariant {
    /// The file as it is.
    AsPublished,
    /// Every pose of the initial guess moved (0.5 m, 20°, seeded).
    Perturbed,
    /// A tenth more loop edges, each between random poses with a random
    /// measurement.
    Outliers10,
}

impl GraphVariant {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "as-published" => Self::AsPublished,
            "perturbed" => Self::Perturbed,
            "outliers-10" => Self::Outliers10,
            _ => return None,
        })
    }
}

/// What a case runs on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Input {
    /// A camera dataset.
    Camera(Source),
    /// A real recording through its rig (beside the corpus), its frame
    /// times from the shared data made into the rig's stamps file.
    Real {
        /// The rig file, relative to the corpus's folder.
        rig: String,
        /// `$PIROUETTE_SHARED/...`: `index stamp` per line; frame `index`
        /// is `frames/index.jpg` beside it.
        frame_times: String,
        /// Every `every`-th frame is chosen.
        every: usize,
    },
    /// An index built from one dataset, queried with another.
    Places {
        /// Indexed.
        index: Source,
        /// Queried.
        query: Source,
    },
    /// `$PIROUETTE_SHARED/laser/LOG.log`, maybe changed.
    Laser {
        /// The log's name without `.log`.
        log: String,
        /// How it is changed.
        variant: LaserVariant,
    },
    /// `$PIROUETTE_SHARED/laser/benchmark/NAME.bag`, scored on its
    /// relations beside Cartographer's published figures.
    Bag {
        /// The bag's name without `.bag`.
        name: String,
        /// Cartographer's published mean translational error, metres ...
        cartographer_trans_m: f64,
        /// ... mean rotational error, degrees ...
        cartographer_rot_deg: f64,
        /// ... and wall clock for the log, seconds.
        cartographer_time_s: f64,
    },
    /// `$PIROUETTE_SHARED/posegraph/FILE.g2o`, maybe changed.
    Graph {
        /// The file's name without `.g2o`.
        file: String,
        /// How it is changed.
        variant: GraphVariant,
        /// The known minimum χ² of the file as published.
        reference_chi2: f64,
    },
}

/// One evaluation case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Case {
    /// Unique and readable: `office-multi`, `room-multi seed 3`,
    /// `intel-corrected:no-odometry`.
    pub id: String,
    /// What it exercises.
    pub kind: Kind,
    /// Whether `--quick` runs it.
    pub quick: bool,
    /// Places of a scene where every place has a look-alike: answers are
    /// right or ambiguous, and none at all is no miss.
    pub look_alike: bool,
    /// What it runs on.
    pub input: Input,
}

impl Case {
    /// The figures a run of this case must give: a target on one of them
    /// that the run leaves out is missed, not met. A places case of a
    /// look-alike scene need not answer (its places may all be
    /// ambiguous), so precision and pose errors are required only where
    /// it does.
    pub fn required(&self) -> &'static [&'static str] {
        match &self.input {
            Input::Camera(_) => CAMERA_FIGURES,
            Input::Real { .. } => REAL_FIGURES,
            Input::Places { .. } if self.look_alike => &PLACES_FIGURES[..3],
            Input::Places { .. } => PLACES_FIGURES,
            Input::Laser {
                variant: LaserVariant::AsRecorded,
                ..
            } => &LASER_FIGURES[..4],
            Input::Laser { .. } => LASER_FIGURES,
            Input::Bag { .. } => BAG_FIGURES,
            Input::Graph {
                variant: GraphVariant::Outliers10,
                ..
            } => OUTLIER_GRAPH_FIGURES,
            Input::Graph { .. } => GRAPH_FIGURES,
        }
    }

    /// Whether the case reads `$PIROUETTE_SHARED`.
    pub fn needs_shared(&self) -> bool {
        let shared = |s: &Source| matches!(s, Source::Shared(_));
        match &self.input {
            Input::Camera(s) => shared(s),
            Input::Places { index, query } => shared(index) || shared(query),
            Input::Real { .. } | Input::Laser { .. } | Input::Bag { .. } | Input::Graph { .. } => true,
        }
    }
}

/// The corpus: targets and cases.
#[derive(Debug, Clone)]
pub struct Corpus {
    /// The corpus file.
    pub path: PathBuf,
    /// Targets per kind and figure.
    pub targets: BTreeMap<Kind, BTreeMap<String, Bound>>,
    /// Every case, in the file's order.
    pub cases: Vec<Case>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CorpusFile {
    format: u32,
    targets: BTreeMap<Kind, BTreeMap<String, Bound>>,
    #[serde(default)]
    camera: Vec<CameraGroup>,
    #[serde(default)]
    real: Vec<RealGroup>,
    #[serde(default)]
    places: Vec<PlacesGroup>,
    #[serde(default)]
    laser: Vec<LaserGroup>,
    #[serde(default)]
    bag: Vec<BagGroup>,
    #[serde(default)]
    graph: Vec<GraphGroup>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraGroup {
    name: Option<String>,
    shared: Option<Vec<String>>,
    scene: Option<String>,
    #[serde(default)]
    seeds: Vec<u64>,
    patch: Option<toml::Table>,
    /// Shared names, or seeds.
    #[serde(default)]
    quick: Vec<toml::Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RealGroup {
    rig: String,
    frame_times: String,
    /// One case per frame choice: every N-th frame.
    every: Vec<usize>,
    #[serde(default)]
    quick: Vec<usize>,
}

impl RealGroup {
    fn expand(&self, cases: &mut Vec<Case>) -> Result<()> {
        let name = Path::new(&self.rig)
            .parent()
            .and_then(|p| p.file_name())
            .map_or(self.rig.clone(), |n| n.to_string_lossy().into_owned());
        for &every in &self.every {
            if !(1..=1000).contains(&every) {
                bail!("real {}: every {every} must be within 1-1000", self.rig);
            }
            cases.push(Case {
                id: format!("{name} every {every}"),
                kind: Kind::Real,
                quick: self.quick.contains(&every),
                look_alike: false,
                input: Input::Real {
                    rig: self.rig.clone(),
                    frame_times: self.frame_times.clone(),
                    every,
                },
            });
        }
        Ok(())
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SourceSpec {
    shared: Option<String>,
    scene: Option<String>,
    patch: Option<toml::Table>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlacesGroup {
    name: Option<String>,
    index: SourceSpec,
    query: SourceSpec,
    /// Index seeds; each query renders with the next seed.
    #[serde(default)]
    seeds: Vec<u64>,
    /// Whether `--quick` runs the group's first pair.
    #[serde(default)]
    quick: bool,
    /// Every place of the scene has a look-alike (`Case::look_alike`).
    #[serde(default)]
    look_alike: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LaserGroup {
    logs: Vec<String>,
    variants: Vec<String>,
    #[serde(default)]
    quick: Vec<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BagGroup {
    name: String,
    cartographer_trans_m: f64,
    cartographer_rot_deg: f64,
    cartographer_time_s: f64,
    #[serde(default)]
    quick: bool,
}

impl BagGroup {
    fn expand(&self, cases: &mut Vec<Case>) -> Result<()> {
        let figures = [
            self.cartographer_trans_m,
            self.cartographer_rot_deg,
            self.cartographer_time_s,
        ];
        if !figures.iter().all(|v| v.is_finite() && *v > 0.0) {
            bail!("bag {}: the published figures must be positive", self.name);
        }
        cases.push(Case {
            id: format!("{}.bag", self.name),
            kind: Kind::Laser,
            quick: self.quick,
            look_alike: false,
            input: Input::Bag {
                name: self.name.clone(),
                cartographer_trans_m: self.cartographer_trans_m,
                cartographer_rot_deg: self.cartographer_rot_deg,
                cartographer_time_s: self.cartographer_time_s,
            },
        });
        Ok(())
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GraphGroup {
    file: String,
    reference_chi2: f64,
    variants: Vec<String>,
    #[serde(default)]
    quick: Vec<String>,
}

/// The stem of a scene name: `corpus/square-room.json` → `square-room`.
fn scene_stem(scene: &str) -> String {
    Path::new(scene)
        .file_stem()
        .map_or(scene.into(), |s| s.to_string_lossy().into_owned())
}

fn patch_json(patch: &Option<toml::Table>) -> Result<Option<serde_json::Value>> {
    patch
        .as_ref()
        .map(|t| serde_json::to_value(t).context("patch"))
        .transpose()
}

impl SourceSpec {
    fn source(&self, seed: u64, label: &str) -> Result<Source> {
        match (&self.shared, &self.scene) {
            (Some(name), None) => Ok(Source::Shared(name.clone())),
            (None, Some(scene)) => Ok(Source::Render {
                scene: scene.clone(),
                seed,
                patch: patch_json(&self.patch)?,
                label: label.to_string(),
            }),
            _ => bail!("a source names exactly one of `shared` and `scene`"),
        }
    }

    fn label(&self) -> String {
        self.shared
            .clone()
            .or(self.scene.as_deref().map(scene_stem))
            .unwrap_or_default()
    }
}

impl Corpus {
    /// Reads and expands a corpus file.
    pub fn read(path: &Path) -> Result<Corpus> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read corpus {}", path.display()))?;
        let file: CorpusFile =
            toml::from_str(&text).with_context(|| format!("{}: not a corpus", path.display()))?;
        if file.format != CORPUS_FORMAT {
            bail!(
                "{}: corpus format {} (this build reads format {CORPUS_FORMAT})",
                path.display(),
                file.format
            );
        }
        for (kind, targets) in &file.targets {
            let known = kind.figures();
            for (figure, bound) in targets {
                if !known.contains(&figure.as_str()) {
                    bail!(
                        "{}: [targets.{}] {figure}: no such figure (a {} case gives {})",
                        path.display(),
                        kind.name(),
                        kind.name(),
                        known.join(", ")
                    );
                }
                bound.check(figure).with_context(|| path.display().to_string())?;
            }
        }
        let mut cases = Vec::new();
        let expand = |cases: &mut Vec<Case>| -> Result<()> {
            for g in &file.camera {
                g.expand(cases)?;
            }
            for g in &file.real {
                g.expand(cases)?;
            }
            for g in &file.places {
                g.expand(cases)?;
            }
            for g in &file.laser {
                g.expand(cases)?;
            }
            for g in &file.bag {
                g.expand(cases)?;
            }
            for g in &file.graph {
                g.expand(cases)?;
            }
            Ok(())
        };
        expand(&mut cases).with_context(|| path.display().to_string())?;
        if cases.len() > MAX_CASES {
            bail!("{}: {} cases, at most {MAX_CASES}", path.display(), cases.len());
        }
        let mut seen = std::collections::HashSet::new();
        if let Some(c) = cases.iter().find(|c| !seen.insert(c.id.clone())) {
            bail!("{}: case `{}` is listed twice", path.display(), c.id);
        }
        Ok(Corpus {
            path: path.to_owned(),
            targets: file.targets,
            cases,
        })
    }
}

/// A `quick` entry as text: `"office-multi"` → `office-multi`, `1` → `1`.
fn quick_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        toml::Value::Integer(i) => i.to_string(),
        other => format!("{other:?}"),
    }
}

impl CameraGroup {
    fn expand(&self, cases: &mut Vec<Case>) -> Result<()> {
        let quick: Vec<String> = self.quick.iter().map(quick_text).collect();
        match (&self.shared, &self.scene) {
            (Some(names), None) => {
                for name in names {
                    cases.push(Case {
                        id: name.clone(),
                        kind: Kind::Camera,
                        quick: quick.contains(name),
                        look_alike: false,
                        input: Input::Camera(Source::Shared(name.clone())),
                    });
                }
            }
            (None, Some(scene)) => {
                if self.seeds.is_empty() {
                    bail!("camera scene {scene}: no seeds");
                }
                let label = self.name.clone().unwrap_or_else(|| scene_stem(scene));
                for &seed in &self.seeds {
                    let source = Source::Render {
                        scene: scene.clone(),
                        seed,
                        patch: patch_json(&self.patch)?,
                        label: label.clone(),
                    };
                    cases.push(Case {
                        id: source.label(),
                        kind: Kind::Camera,
                        quick: quick.contains(&seed.to_string()),
                        look_alike: false,
                        input: Input::Camera(source),
                    });
                }
            }
            _ => bail!("a camera group names exactly one of `shared` and `scene`"),
        }
        Ok(())
    }
}

impl PlacesGroup {
    fn expand(&self, cases: &mut Vec<Case>) -> Result<()> {
        let index_label = self.index.label();
        let query_label = self.name.clone().unwrap_or_else(|| self.query.label());
        let seeds = if self.seeds.is_empty() {
            vec![0]
        } else {
            self.seeds.clone()
        };
        for (i, &seed) in seeds.iter().enumerate() {
            let index = self.index.source(seed, &index_label)?;
            let query = self.query.source(seed + 1, &query_label)?;
            cases.push(Case {
                id: format!("{} / {}", index.label(), query.label()),
                kind: Kind::Places,
                quick: self.quick && i == 0,
                look_alike: self.look_alike,
                input: Input::Places { index, query },
            });
        }
        Ok(())
    }
}

impl LaserGroup {
    fn expand(&self, cases: &mut Vec<Case>) -> Result<()> {
        for log in &self.logs {
            for v in &self.variants {
                let variant = LaserVariant::parse(v).with_context(|| {
                    format!("laser variant `{v}`: as-recorded, no-odometry, noisy-odometry, every-N or every-N-no-odometry")
                })?;
                let id = format!("{log}:{v}");
                cases.push(Case {
                    quick: self.quick.contains(&id),
                    look_alike: false,
                    id,
                    kind: Kind::Laser,
                    input: Input::Laser {
                        log: log.clone(),
                        variant,
                    },
                });
            }
        }
        Ok(())
    }
}

impl GraphGroup {
    fn expand(&self, cases: &mut Vec<Case>) -> Result<()> {
        if !(self.reference_chi2.is_finite() && self.reference_chi2 > 0.0) {
            bail!("graph {}: reference_chi2 must be positive", self.file);
        }
        for v in &self.variants {
            let variant = GraphVariant::parse(v)
                .with_context(|| format!("graph variant `{v}`: as-published, perturbed or outliers-10"))?;
            let id = format!("{}:{v}", self.file);
            cases.push(Case {
                quick: self.quick.contains(&id),
                look_alike: false,
                id,
                kind: Kind::Graph,
                input: Input::Graph {
                    file: self.file.clone(),
                    variant,
                    reference_chi2: self.reference_chi2,
                },
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_projects_corpus_expands_and_names_every_kind() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/corpus.toml");
        let corpus = Corpus::read(&path).unwrap();
        for kind in Kind::ALL {
            assert!(
                corpus.cases.iter().any(|c| c.kind == kind && c.quick),
                "{kind:?} quick"
            );
            assert!(corpus.targets.contains_key(&kind), "{kind:?} targets");
        }
        assert!(corpus.cases.iter().any(|c| c.id == "room-multi-dark seed 2"));
        assert!(corpus
            .cases
            .iter()
            .any(|c| c.id == "intel-corrected:every-3-no-odometry"));
    }

    #[test]
    fn variants_parse_and_nonsense_is_refused() {
        assert_eq!(
            LaserVariant::parse("every-3-no-odometry"),
            Some(LaserVariant::Every {
                keep: 3,
                odometry: false
            })
        );
        assert_eq!(LaserVariant::parse("every-1"), None);
        assert_eq!(LaserVariant::parse("every-x"), None);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.toml");
        std::fs::write(
            &p,
            "format = 1\n[targets]\n[[laser]]\nlogs = [\"a\"]\nvariants = [\"sideways\"]\n",
        )
        .unwrap();
        let err = format!("{:#}", Corpus::read(&p).unwrap_err());
        assert!(err.contains("c.toml") && err.contains("sideways"), "{err}");
        std::fs::write(&p, "format = 2\n[targets]\n").unwrap();
        assert!(format!("{:#}", Corpus::read(&p).unwrap_err()).contains("format 2"));
    }

    #[test]
    fn bounds_hold_at_their_edges() {
        let b = Bound {
            max: Some(0.02),
            ..Bound::default()
        };
        assert!(b.holds(0.02) && !b.holds(0.0201));
        let b = Bound {
            min: Some(1.0),
            ..Bound::default()
        };
        assert!(b.holds(1.0) && !b.holds(0.99));
    }

    #[test]
    fn targets_name_known_figures_and_gates_parse() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.toml");
        let read = |text: &str| {
            std::fs::write(&p, text).unwrap();
            Corpus::read(&p).map_err(|e| format!("{e:#}"))
        };
        let err = read("format = 1\n[targets.places]\nprecission = { min = 1.0 }\n").unwrap_err();
        assert!(
            err.contains("c.toml") && err.contains("precission") && err.contains("no such figure"),
            "{err}"
        );
        let err =
            read("format = 1\n[targets.camera]\nf1 = { min = 0.9, gate = { min = 0.95 } }\n").unwrap_err();
        assert!(err.contains("looser"), "{err}");
        let err = read("format = 1\n[targets.camera]\nf1 = { gate = true }\n").unwrap_err();
        assert!(err.contains("min") && err.contains("max"), "{err}");
        let c = read(
            "format = 1\n[targets.camera]\nf1 = { min = 0.9, gate = true }\nmissed = { max = 0.02, gate = { max = 0.06 } }\n",
        )
        .unwrap();
        let (f1, missed) = (c.targets[&Kind::Camera]["f1"], c.targets[&Kind::Camera]["missed"]);
        assert!(!f1.gate_fails(Some(0.9)) && f1.gate_fails(Some(0.89)) && f1.gate_fails(None));
        assert!(!missed.gate_fails(Some(0.05)) && missed.gate_fails(Some(0.061)));
        assert_eq!(missed.gate_text().as_deref(), Some("≤ 0.06"));
        let ungated = Bound {
            max: Some(0.02),
            ..Bound::default()
        };
        assert!(!ungated.gate_fails(Some(1.0)) && !ungated.gate_fails(None));
    }
}
