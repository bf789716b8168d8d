//! The cases' inputs, made once by this build in `OUT/data/` and read by
//! every binary measured: renders of scenes, changed laser logs, harder
//! pose graphs.

use super::corpus::{GraphVariant, LaserVariant, Source};
use anyhow::{bail, Context, Result};
use pirouette_geom::Pose2;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::io::{BufRead, BufWriter, Write};
use std::path::{Path, PathBuf};

/// Where shared data and made inputs are.
#[derive(Debug, Clone)]
pub struct Places {
    /// `$PIROUETTE_SHARED`, if set.
    pub shared: Option<PathBuf>,
    /// The corpus file's folder (scene files named in it).
    pub corpus_dir: PathBuf,
    /// `OUT/data`.
    pub data: PathBuf,
    /// Held while an input is made, so that cases run at once never make
    /// the same one twice.
    pub making: std::sync::Arc<std::sync::Mutex<()>>,
}

impl Places {
    /// A file of the shared data, checked to be there.
    pub fn shared_file(&self, sub: &str) -> Result<PathBuf> {
        self.shared(sub)
    }

    fn shared(&self, sub: &str) -> Result<PathBuf> {
        let Some(root) = &self.shared else {
            bail!("needs the shared data: set PIROUETTE_SHARED");
        };
        let p = root.join(sub);
        if !p.exists() {
            bail!("{} is missing", p.display());
        }
        Ok(p)
    }

    /// A real recording's rig, made here on first use: the rig beside the
    /// corpus with every path made absolute, the shared frame times
    /// written as its stamps file, every `every`-th frame chosen.
    pub fn real_rig(&self, rig: &str, frame_times: &str, every: usize) -> Result<PathBuf> {
        let src = self.corpus_dir.join(rig);
        let times = self.shared(frame_times)?;
        let set = times.parent().unwrap_or(Path::new(".")).to_owned();
        let name = slug(&format!("{}-every-{every}", rig.trim_end_matches(".json")));
        let dir = self.data.join("real").join(name);
        let out = dir.join("rig.json");
        let _making = self.making.lock().unwrap_or_else(|e| e.into_inner());
        if out.is_file() {
            return Ok(out);
        }
        let text = std::fs::read_to_string(&src).with_context(|| format!("cannot read {}", src.display()))?;
        let mut r: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{}: bad JSON", src.display()))?;
        let src_dir = src.parent().unwrap_or(Path::new("."));
        let truth_name = (r["truth"].as_str())
            .and_then(|t| Path::new(t).file_name())
            .with_context(|| format!("{}: no truth file named", src.display()))?
            .to_owned();
        let calibration = (r["calibration"].as_str())
            .with_context(|| format!("{}: no calibration named", src.display()))?;
        r["calibration"] = src_dir.join(calibration).display().to_string().into();
        r["images"] = set.display().to_string().into();
        r["truth"] = set.join(truth_name).display().to_string().into();
        r["stamps"] = dir.join("stamps.txt").display().to_string().into();
        r["select"] = serde_json::json!({ "every": every });
        // `index stamp` lines become `stamp frames/index.jpg`.
        let mut stamps = String::new();
        let lines =
            std::fs::read_to_string(&times).with_context(|| format!("cannot read {}", times.display()))?;
        for (n, line) in lines.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let mut f = line.split_whitespace();
            let (Some(index), Some(t)) = (f.next(), f.next()) else {
                bail!("{}:{}: expected `index stamp`", times.display(), n + 1);
            };
            stamps.push_str(&format!("{t} frames/{index}.jpg\n"));
        }
        std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
        pirouette_io::atomic_write(&dir.join("stamps.txt"), stamps.as_bytes())?;
        pirouette_io::atomic_write(&out, r.to_string().as_bytes())?;
        Ok(out)
    }

    /// A camera dataset's folder, rendered here on first use.
    pub fn dataset(&self, source: &Source) -> Result<PathBuf> {
        match source {
            Source::Shared(name) => self.shared(&format!("datasets/{name}")),
            Source::Render {
                scene,
                seed,
                patch,
                label,
            } => {
                let key = {
                    use std::hash::{Hash, Hasher};
                    let mut h = std::collections::hash_map::DefaultHasher::new();
                    (scene, patch.as_ref().map(|p| p.to_string())).hash(&mut h);
                    h.finish() & 0xffff_ffff
                };
                let dir = (self.data.join("renders")).join(slug(&format!("{label}-{seed}-{key:08x}")));
                let _making = self.making.lock().unwrap_or_else(|e| e.into_inner());
                if dir.join("dataset.json").is_file() {
                    return Ok(dir);
                }
                let scene = self.scene(scene, patch.as_ref())?;
                let tmp = dir.with_extension("partial");
                let _ = std::fs::remove_dir_all(&tmp);
                pirouette_sim::render_dataset(&scene, *seed, &tmp, |_, _| {})
                    .with_context(|| format!("rendering {label} seed {seed}"))?;
                std::fs::rename(&tmp, &dir)
                    .with_context(|| format!("cannot move the render to {}", dir.display()))?;
                Ok(dir)
            }
        }
    }

    /// A scene by built-in name or file beside the corpus, with `patch`
    /// merged in.
    fn scene(&self, scene: &str, patch: Option<&serde_json::Value>) -> Result<pirouette_sim::Scene> {
        let (mut json, what) = match pirouette_sim::Scene::builtin(scene) {
            Some(s) => (serde_json::to_value(s)?, format!("built-in scene {scene}")),
            None => {
                let path = self.corpus_dir.join(scene);
                let s = pirouette_sim::Scene::from_file(&path)?;
                (serde_json::to_value(s)?, path.display().to_string())
            }
        };
        if let Some(p) = patch {
            merge(&mut json, p);
        }
        let s: pirouette_sim::Scene =
            serde_json::from_value(json).with_context(|| format!("{what}: patch"))?;
        s.validate().with_context(|| format!("{what} with its patch"))?;
        Ok(s)
    }

    /// A laser log, changed as `variant` says.
    pub fn laser_log(&self, log: &str, variant: LaserVariant) -> Result<PathBuf> {
        let src = self.shared(&format!("laser/{log}.log"))?;
        if variant == LaserVariant::AsRecorded {
            return Ok(src);
        }
        let out = self
            .data
            .join("laser")
            // The name's version changes with what a variant holds.
            .join(slug(&format!("{log}-{variant:?}-v2")) + ".log");
        let _making = self.making.lock().unwrap_or_else(|e| e.into_inner());
        if !out.is_file() {
            write_laser_variant(&src, &out, variant)?;
        }
        Ok(out)
    }

    /// A pose graph, changed as `variant` says.
    pub fn graph(&self, file: &str, variant: GraphVariant) -> Result<PathBuf> {
        let src = self.shared(&format!("posegraph/{file}.g2o"))?;
        if variant == GraphVariant::AsPublished {
            return Ok(src);
        }
        let out = self
            .data
            .join("graph")
            .join(slug(&format!("{file}-{variant:?}")) + ".g2o");
        let _making = self.making.lock().unwrap_or_else(|e| e.into_inner());
        if !out.is_file() {
            write_graph_variant(&src, &out, variant)?;
        }
        Ok(out)
    }
}

/// A file name from free text.
fn slug(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect()
}

/// Merges `patch` into `into`: objects key by key, anything else replaced.
pub fn merge(into: &mut serde_json::Value, patch: &serde_json::Value) {
    match (into, patch) {
        (serde_json::Value::Object(a), serde_json::Value::Object(b)) => {
            for (k, v) in b {
                merge(a.entry(k.clone()).or_insert(serde_json::Value::Null), v);
            }
        }
        (a, b) => *a = b.clone(),
    }
}

/// One scan line of a FLASER log with its corrected pose, and the raw
/// odometry step to the next scan.
struct LoggedScan {
    line: String,
    pose: Pose2,
    /// `pose⁻¹ · last ODOM pose before the next scan`; identity where none
    /// moved.
    step: Pose2,
    stamp: String,
}

fn read_flaser(src: &Path) -> Result<Vec<LoggedScan>> {
    let file = std::fs::File::open(src).with_context(|| format!("cannot open {}", src.display()))?;
    let mut scans: Vec<LoggedScan> = Vec::new();
    let mut last_odom: Option<Pose2> = None;
    let close = |scans: &mut Vec<LoggedScan>, odom: Option<Pose2>| {
        if let (Some(s), Some(o)) = (scans.last_mut(), odom) {
            s.step = s.pose.inverse() * o;
        }
    };
    for (i, line) in std::io::BufReader::new(file).lines().enumerate() {
        let line = line.with_context(|| format!("{}:{}", src.display(), i + 1))?;
        let f: Vec<&str> = line.split_whitespace().collect();
        let num = |k: usize| -> Result<f64> {
            (f.get(k).and_then(|v| v.parse().ok()))
                .with_context(|| format!("{}:{}: field {k}", src.display(), i + 1))
        };
        match f.first() {
            Some(&"FLASER") => {
                close(&mut scans, last_odom.take());
                let n = num(1)? as usize;
                let pose = Pose2::new(num(n + 2)?, num(n + 3)?, num(n + 4)?);
                let stamp = f.get(n + 8).unwrap_or(&"0").to_string();
                scans.push(LoggedScan {
                    line,
                    pose,
                    step: Pose2::IDENTITY,
                    stamp,
                });
            }
            Some(&"ODOM") if !scans.is_empty() => last_odom = Some(Pose2::new(num(1)?, num(2)?, num(3)?)),
            Some(&"ROBOTLASER1") | Some(&"RLASER") => {
                bail!(
                    "{}:{}: variants are made of FLASER logs only",
                    src.display(),
                    i + 1
                )
            }
            _ => {}
        }
    }
    close(&mut scans, last_odom);
    if scans.is_empty() {
        bail!("{}: no FLASER scans", src.display());
    }
    Ok(scans)
}

/// Writes `src` changed as `variant` says: scan lines kept as they are, one
/// `ODOM` line after each kept scan with the (composed, noisy) odometry
/// up to the next kept scan, or none.
pub fn write_laser_variant(src: &Path, out: &Path, variant: LaserVariant) -> Result<()> {
    let scans = read_flaser(src)?;
    let (keep, odometry, noise) = match variant {
        LaserVariant::AsRecorded => (1, true, false),
        LaserVariant::NoOdometry => (1, false, false),
        LaserVariant::NoisyOdometry => (1, true, true),
        LaserVariant::Every { keep, odometry } => (keep, odometry, false),
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let scale = Normal::new(1.0, 0.05).context("noise")?;
    let turn = Normal::new(0.0, 2f64.to_radians()).context("noise")?;
    let mut text = Vec::new();
    {
        let mut w = BufWriter::new(&mut text);
        writeln!(w, "# {} as the scoreboard's variant {variant:?}", src.display())?;
        for chunk in scans.chunks(keep) {
            let first = &chunk[0];
            if !odometry {
                // A raw log reads its odometry from these fields: zeroed,
                // they say the step has none.
                writeln!(w, "{}", without_odometry_fields(&first.line))?;
                continue;
            }
            writeln!(w, "{}", first.line)?;
            let mut step = chunk.iter().fold(Pose2::IDENTITY, |acc, s| acc * s.step);
            if noise {
                let k = scale.sample(&mut rng);
                step = Pose2::new(step.x * k, step.y * k, step.theta + turn.sample(&mut rng));
            }
            let o = first.pose * step;
            writeln!(
                w,
                "ODOM {} {} {} 0 0 0 {} pirouette {}",
                o.x, o.y, o.theta, first.stamp, first.stamp
            )?;
        }
        w.flush()?;
    }
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    pirouette_io::atomic_write(out, &text)?;
    Ok(())
}

/// An `FLASER` line with its odometry triple (the three fields after the
/// pose) set to zero.
fn without_odometry_fields(line: &str) -> String {
    let mut f: Vec<&str> = line.split_whitespace().collect();
    let n = f.get(1).and_then(|v| v.parse::<usize>().ok()).unwrap_or(0);
    for k in n + 5..n + 8 {
        if let Some(v) = f.get_mut(k) {
            *v = "0";
        }
    }
    f.join(" ")
}

/// Writes `src` made harder as `variant` says.
pub fn write_graph_variant(src: &Path, out: &Path, variant: GraphVariant) -> Result<()> {
    let mut g = pirouette_io::read_g2o(src)?;
    if !g.has_vertices {
        pirouette_graph::init::chain(&mut g.graph).with_context(|| format!("{}: chaining", src.display()))?;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    match variant {
        GraphVariant::AsPublished => {}
        GraphVariant::Perturbed => {
            let shift = Normal::new(0.0, 0.5).context("noise")?;
            let turn = Normal::new(0.0, 20f64.to_radians()).context("noise")?;
            for p in g.graph.poses.iter_mut().skip(1) {
                *p = *p
                    * Pose2::new(
                        shift.sample(&mut rng),
                        shift.sample(&mut rng),
                        turn.sample(&mut rng),
                    );
            }
        }
        GraphVariant::Outliers10 => {
            let n = g.graph.poses.len();
            let extra = g.graph.edges.len() / 10;
            if n < 20 {
                bail!("{}: too few poses for outliers", src.display());
            }
            for _ in 0..extra {
                let from = rng.random_range(0..n);
                let to = loop {
                    let j = rng.random_range(0..n);
                    if from.abs_diff(j) > 10 {
                        break j;
                    }
                };
                let model = g.graph.edges[rng.random_range(0..g.graph.edges.len())];
                let measurement = Pose2::new(
                    rng.random_range(-5.0..5.0),
                    rng.random_range(-5.0..5.0),
                    rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
                );
                g.graph.edges.push(pirouette_graph::Edge::new(
                    from,
                    to,
                    measurement,
                    model.information,
                ));
            }
        }
    }
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    pirouette_io::write_g2o(out, &g)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A log of three scans 1 m apart along x; the odometry says 0.9 m.
    fn tiny_log(dir: &Path) -> PathBuf {
        let p = dir.join("t.log");
        let mut s = String::new();
        for k in 0..3 {
            let x = k as f64;
            s += &format!("FLASER 2 1.0 1.0 {x} 0 0 {x} 0 0 {k}.0 h {k}.0\n");
            s += &format!("ODOM {x} 0 0 0 0 0 0 h 0\n");
            s += &format!("ODOM {} 0 0 0 0 0 {k}.5 h {k}.5\n", x + 0.9);
        }
        std::fs::write(&p, s).unwrap();
        p
    }

    #[test]
    fn every_second_scan_composes_the_odometry_between() {
        let dir = tempfile::tempdir().unwrap();
        let src = tiny_log(dir.path());
        let out = dir.path().join("v.log");
        write_laser_variant(
            &src,
            &out,
            LaserVariant::Every {
                keep: 2,
                odometry: true,
            },
        )
        .unwrap();
        let scans: Vec<_> = pirouette_io::CarmenReader::open(&out)
            .unwrap()
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        assert_eq!(scans.len(), 2);
        // Two odometry steps of 0.9 m from scan 0's pose.
        let odo = scans[1].odometry.unwrap();
        assert!((odo.x - 1.8).abs() < 1e-12 && odo.y.abs() < 1e-12, "{odo:?}");
        write_laser_variant(&src, &out, LaserVariant::NoOdometry).unwrap();
        let scans: Vec<_> = pirouette_io::CarmenReader::open(&out)
            .unwrap()
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        assert_eq!(scans.len(), 3);
        assert!(scans.iter().all(|s| s.odometry.is_none()));
    }

    #[test]
    fn patches_merge_tables_and_replace_values() {
        let mut a = serde_json::json!({"look": {"exposure": 1.0, "ambient": 0.4}, "route": {"w": [1, 2]}});
        merge(
            &mut a,
            &serde_json::json!({"look": {"exposure": 0.5}, "route": {"w": [3]}}),
        );
        assert_eq!(
            a,
            serde_json::json!({"look": {"exposure": 0.5, "ambient": 0.4}, "route": {"w": [3]}})
        );
    }
}
