//! Simulated 2D laser logs in the CARMEN text format: a floor of walls,
//! a robot's path through it, each scan ray cast with range noise, and
//! raw odometry that errs the way a real robot's does (a scale error and
//! jitter on every step).
//!
//! The recorded pose of each scan is its true pose, so a log's own poses
//! are ground truth for `pirouette eval laser`.

use pirouette_geom::Pose2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::FRAC_PI_2;
use std::io::Write;

/// Wall segments `[x0, y0, x1, y1]`, metres.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Walls {
    segments: Vec<[f64; 4]>,
}

impl Walls {
    /// The walls of the segments given.
    pub fn new(segments: Vec<[f64; 4]>) -> Self {
        Self { segments }
    }

    /// The segments.
    pub fn segments(&self) -> &[[f64; 4]] {
        &self.segments
    }

    /// Adds the four walls of the rectangle `x0..x1` × `y0..y1`.
    pub fn rectangle(&mut self, x0: f64, y0: f64, x1: f64, y1: f64) {
        self.segments.extend([
            [x0, y0, x1, y0],
            [x1, y0, x1, y1],
            [x1, y1, x0, y1],
            [x0, y1, x0, y0],
        ]);
    }

    /// A 12 × 8 m room around a 4 × 2 m block (a ring corridor), with
    /// boxes along the walls so that no stretch is a featureless corridor.
    pub fn ring() -> Self {
        let mut w = Self::default();
        w.rectangle(0.0, 0.0, 12.0, 8.0);
        w.rectangle(4.0, 3.0, 8.0, 5.0);
        for (x, y) in [
            (1.0, 0.0),
            (5.5, 0.0),
            (9.5, 0.0),
            (11.6, 3.0),
            (3.0, 7.6),
            (7.5, 7.6),
            (0.0, 5.0),
        ] {
            w.rectangle(x, y, x + 0.4, y + 0.4);
        }
        w.rectangle(5.5, 2.6, 6.0, 3.0);
        w
    }

    /// The nearest wall along the ray from `o` in direction `d` (a unit
    /// vector), metres.
    pub fn cast(&self, o: [f64; 2], d: [f64; 2]) -> Option<f64> {
        let mut best: Option<f64> = None;
        for &[x0, y0, x1, y1] in &self.segments {
            let (ex, ey) = (x1 - x0, y1 - y0);
            let den = d[0] * ey - d[1] * ex;
            if den.abs() < 1e-12 {
                continue;
            }
            let (wx, wy) = (x0 - o[0], y0 - o[1]);
            let t = (wx * ey - wy * ex) / den;
            let u = (wx * d[1] - wy * d[0]) / den;
            if t > 0.0 && (0.0..=1.0).contains(&u) && best.is_none_or(|b| t < b) {
                best = Some(t);
            }
        }
        best
    }
}

/// An office floor: `columns` × `rows` square blocks of offices between
/// corridors, a crate here and there along the corridor walls, and a robot
/// that wanders the corridors for ever.
#[derive(Debug, Clone, PartialEq)]
pub struct OfficeFloor {
    /// Blocks across.
    pub columns: usize,
    /// Blocks up.
    pub rows: usize,
    /// A block's side, metres.
    pub block_m: f64,
    /// A corridor's width, metres.
    pub corridor_m: f64,
    /// The robot's step between scans along a corridor, metres.
    pub step_m: f64,
    /// The robot's step between scans turning at a crossing, radians.
    pub turn_rad: f64,
}

impl Default for OfficeFloor {
    /// 4 × 4 blocks of 6 m between 2.5 m corridors (36.5 m square); steps
    /// of 0.2 m and 30°.
    fn default() -> Self {
        Self {
            columns: 4,
            rows: 4,
            block_m: 6.0,
            corridor_m: 2.5,
            step_m: 0.2,
            turn_rad: 30f64.to_radians(),
        }
    }
}

impl OfficeFloor {
    /// The centre of crossing `(i, j)`, metres.
    fn crossing(&self, i: usize, j: usize) -> [f64; 2] {
        let pitch = self.block_m + self.corridor_m;
        [
            self.corridor_m / 2.0 + i as f64 * pitch,
            self.corridor_m / 2.0 + j as f64 * pitch,
        ]
    }

    /// The outer walls, the blocks, and crates (0.3–0.6 m) placed by
    /// `seed` along the blocks' sides.
    pub fn walls(&self, seed: u64) -> Walls {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let pitch = self.block_m + self.corridor_m;
        let mut w = Walls::default();
        let side = self.corridor_m + self.columns as f64 * pitch;
        let top = self.corridor_m + self.rows as f64 * pitch;
        w.rectangle(0.0, 0.0, side, top);
        for i in 0..self.columns {
            for j in 0..self.rows {
                let (x0, y0) = (
                    self.corridor_m + i as f64 * pitch,
                    self.corridor_m + j as f64 * pitch,
                );
                let (x1, y1) = (x0 + self.block_m, y0 + self.block_m);
                w.rectangle(x0, y0, x1, y1);
                // Two crates on each side of the block, against its wall.
                for s in 0..4 {
                    for _ in 0..2 {
                        let along = rng.random_range(0.5..self.block_m - 1.0);
                        let size = rng.random_range(0.3..0.6);
                        let (cx, cy) = match s {
                            0 => (x0 + along, y0 - size),
                            1 => (x1, y0 + along),
                            2 => (x0 + along, y1),
                            _ => (x0 - size, y0 + along),
                        };
                        w.rectangle(cx, cy, cx + size, cy + size);
                    }
                }
            }
        }
        w
    }

    /// The robot's path, one pose per scan, from crossing `(0, 0)`
    /// facing east: along a corridor to the next crossing, then a turn
    /// chosen by `seed` (never straight back), and on for ever.
    pub fn wander(&self, seed: u64) -> impl Iterator<Item = Pose2> + '_ {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (mut i, mut j, mut heading) = (0usize, 0usize, 0i32);
        let [x, y] = self.crossing(0, 0);
        let mut pending = vec![Pose2::new(x, y, 0.0)];
        let mut theta = 0.0;
        std::iter::from_fn(move || {
            if pending.is_empty() {
                // The next corridor: any way out of this crossing but back.
                let ways: Vec<i32> = (0..4)
                    .filter(|&h| (h + 2) % 4 != heading)
                    .filter(|&h| match h {
                        0 => i < self.columns,
                        1 => j < self.rows,
                        2 => i > 0,
                        _ => j > 0,
                    })
                    .collect();
                if ways.is_empty() {
                    return None;
                }
                let next = ways[rng.random_range(0..ways.len())];
                let [x, y] = self.crossing(i, j);
                // Turn on the spot, the short way, in steps.
                let turn = (next - heading + 4) % 4;
                let quarter = match turn {
                    1 => 1.0,
                    3 => -1.0,
                    _ => 0.0,
                };
                let steps = (FRAC_PI_2 / self.turn_rad).round().max(1.0) as usize;
                if quarter != 0.0 {
                    for s in 1..=steps {
                        let th = theta + quarter * FRAC_PI_2 * s as f64 / steps as f64;
                        pending.push(Pose2::new(x, y, th));
                    }
                }
                theta += quarter * FRAC_PI_2;
                heading = next;
                match next {
                    0 => i += 1,
                    1 => j += 1,
                    2 => i -= 1,
                    _ => j -= 1,
                }
                let [x1, y1] = self.crossing(i, j);
                let len = (x1 - x).hypot(y1 - y);
                let steps = (len / self.step_m).round().max(1.0) as usize;
                for s in 1..=steps {
                    let f = s as f64 / steps as f64;
                    pending.push(Pose2::new(x + f * (x1 - x), y + f * (y1 - y), theta));
                }
                pending.reverse();
            }
            pending.pop()
        })
    }
}

/// The line a scanner writes its scans as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogLine {
    /// `FLASER`: a 180° front laser, beams from −90°.
    Flaser,
    /// `ROBOTLASER1`: any layout, written in the line.
    RobotLaser,
}

/// A simulated scanner and robot.
#[derive(Debug, Clone, PartialEq)]
pub struct LogSim {
    /// Beams per scan.
    pub beams: usize,
    /// The first beam's bearing, radians (counter-clockwise, 0 ahead).
    pub first_bearing_rad: f64,
    /// Between beams, radians.
    pub beam_step_rad: f64,
    /// The scanner's maximum range (written where nothing is hit), metres.
    pub max_range_m: f64,
    /// Range noise, one σ, metres.
    pub range_noise_m: f64,
    /// How the scans are written.
    pub line: LogLine,
    /// Raw odometry between scans: each step's move scaled by this ...
    pub odometry_move_scale: f64,
    /// ... its turn by this ...
    pub odometry_turn_scale: f64,
    /// ... and each of x, y, θ jittered uniformly by up to this (metres,
    /// radians). `None` of the three: the log repeats each scan's pose as
    /// its odometry (a log without raw odometry).
    pub odometry_jitter: Option<f64>,
}

impl LogSim {
    /// A 180° scanner of 180 beams 1° apart (`FLASER`), 1 cm range noise,
    /// 81.83 m written for no return; odometry 4 % long on moves and 3 %
    /// on turns, jittered by up to 1 cm and 0.01 rad.
    pub fn sick() -> Self {
        Self {
            beams: 180,
            first_bearing_rad: -FRAC_PI_2,
            beam_step_rad: 1f64.to_radians(),
            max_range_m: 81.83,
            range_noise_m: 0.01,
            line: LogLine::Flaser,
            odometry_move_scale: 1.04,
            odometry_turn_scale: 1.03,
            odometry_jitter: Some(0.01),
        }
    }

    /// A 270° scanner of 1,081 beams 0.25° apart and 30 m reach
    /// (`ROBOTLASER1`), otherwise as [`LogSim::sick`].
    pub fn hokuyo() -> Self {
        Self {
            beams: 1081,
            first_bearing_rad: -135f64.to_radians(),
            beam_step_rad: 0.25f64.to_radians(),
            max_range_m: 30.0,
            line: LogLine::RobotLaser,
            ..Self::sick()
        }
    }

    /// Writes the log of `path` among `walls` to `out`, the scans numbered
    /// from 0 and 0.2 s apart; scans whose number `blind` holds return
    /// nothing (a laser covered). Random draws from `seed`.
    pub fn write(
        &self,
        out: &mut impl Write,
        walls: &Walls,
        path: impl IntoIterator<Item = Pose2>,
        blind: impl Fn(usize) -> bool,
        seed: u64,
    ) -> std::io::Result<()> {
        let mut log = LogWriter::new(self, walls, seed)?;
        log.header(out)?;
        let mut path = path.into_iter().peekable();
        while let Some(p) = path.next() {
            let blinded = blind(log.scans);
            log.scan(out, &p, path.peek(), blinded)?;
        }
        Ok(())
    }
}

/// Writes a simulated log a scan at a time (see [`LogSim::write`]).
#[derive(Debug)]
pub struct LogWriter<'a> {
    sim: &'a LogSim,
    walls: &'a Walls,
    rng: ChaCha8Rng,
    noise: Normal<f64>,
    line: String,
    /// Scans written.
    pub scans: usize,
}

impl<'a> LogWriter<'a> {
    /// Nothing written yet; random draws from `seed`.
    pub fn new(sim: &'a LogSim, walls: &'a Walls, seed: u64) -> std::io::Result<Self> {
        Ok(Self {
            sim,
            walls,
            rng: ChaCha8Rng::seed_from_u64(seed),
            noise: Normal::new(0.0, sim.range_noise_m.max(0.0)).map_err(std::io::Error::other)?,
            line: String::new(),
            scans: 0,
        })
    }

    /// The log's opening lines.
    pub fn header(&self, out: &mut impl Write) -> std::io::Result<()> {
        writeln!(
            out,
            "# a simulated log\nPARAM robot_frontlaser_offset 0.0 nohost 0"
        )
    }

    /// Writes the scan at `p` (returning nothing if `blind`), its pose
    /// repeated as odometry, and the odometry of the step to `next`.
    pub fn scan(
        &mut self,
        out: &mut impl Write,
        p: &Pose2,
        next: Option<&Pose2>,
        blind: bool,
    ) -> std::io::Result<()> {
        use std::fmt::Write as _;
        let sim = self.sim;
        let t = self.scans as f64 * 0.2;
        self.scans += 1;
        self.line.clear();
        for i in 0..sim.beams {
            let b = p.theta + sim.first_bearing_rad + i as f64 * sim.beam_step_rad;
            let hit = self.walls.cast([p.x, p.y], [b.cos(), b.sin()]);
            match hit.filter(|&r| !blind && r < sim.max_range_m) {
                Some(r) => write!(self.line, " {:.3}", r + self.noise.sample(&mut self.rng)),
                None => write!(self.line, " {}", sim.max_range_m),
            }
            .map_err(std::io::Error::other)?;
        }
        let (x, y, th) = (p.x, p.y, p.theta);
        let (n, line) = (sim.beams, &self.line);
        match sim.line {
            LogLine::Flaser => writeln!(out, "FLASER {n}{line} {x} {y} {th} {x} {y} {th} {t} sim {t}")?,
            LogLine::RobotLaser => writeln!(
                out,
                "ROBOTLASER1 0 {} {} {} {} 0.01 0 {n}{line} 0 {x} {y} {th} {x} {y} {th} 0 0 0.5 0.3 0 {t} sim {t}",
                sim.first_bearing_rad,
                sim.beam_step_rad * (n.max(1) - 1) as f64,
                sim.beam_step_rad,
                sim.max_range_m,
            )?,
        }
        // The odometry restarts from the scan's pose.
        writeln!(out, "ODOM {x} {y} {th} 0 0 0 0 sim 0")?;
        if let (Some(jitter), Some(next)) = (sim.odometry_jitter, next) {
            let step = p.between(next);
            let mut j = || self.rng.random_range(-jitter..=jitter);
            let noisy = Pose2::new(
                step.x * sim.odometry_move_scale + j(),
                step.y * sim.odometry_move_scale + j(),
                step.theta * sim.odometry_turn_scale + j(),
            );
            let odom = *p * noisy;
            let t = t + 0.1;
            writeln!(out, "ODOM {} {} {} 0 0 0 {t} sim {t}", odom.x, odom.y, odom.theta)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ray_meets_the_nearest_wall() {
        let w = Walls::ring();
        // From (2, 1.5) east: the block's west side at x = 4 is above the
        // ray (y 3..5), so the room's east wall at 12 is hit.
        assert!((w.cast([2.0, 1.5], [1.0, 0.0]).unwrap() - 10.0).abs() < 1e-12);
        // North from (6, 1.5): the crate on the block's south side, y 2.6.
        assert!((w.cast([5.8, 1.5], [0.0, 1.0]).unwrap() - 1.1).abs() < 1e-12);
        assert!(Walls::default().cast([0.0, 0.0], [1.0, 0.0]).is_none());
    }

    #[test]
    fn the_wanderer_keeps_to_the_corridors_in_even_steps() {
        let floor = OfficeFloor::default();
        let walls = floor.walls(1);
        let path: Vec<Pose2> = floor.wander(2).take(5000).collect();
        for w in path.windows(2) {
            let step = w[0].between(&w[1]);
            let moved = step.translation().norm();
            let turned = step.theta.abs();
            // Either a move ahead of at most a step or a turn on the spot.
            assert!(
                (moved <= floor.step_m + 1e-9 && turned < 1e-9 && step.y.abs() < 1e-9)
                    || (moved < 1e-9 && (turned - floor.turn_rad).abs() < 1e-9),
                "{step:?}"
            );
            // Never through a wall: the straight line between them is free.
            let d = [w[1].x - w[0].x, w[1].y - w[0].y];
            if moved > 0.0 {
                let hit = walls.cast([w[0].x, w[0].y], [d[0] / moved, d[1] / moved]);
                assert!(hit.is_none_or(|h| h > moved));
            }
        }
        // It visits the whole floor.
        let (xs, ys): (Vec<f64>, Vec<f64>) = path.iter().map(|p| (p.x, p.y)).unzip();
        let far = |v: &[f64]| v.iter().cloned().fold(f64::MIN, f64::max);
        assert!(far(&xs) > 30.0 && far(&ys) > 30.0);
    }

    #[test]
    fn a_log_line_per_scan_holds_the_true_ranges() {
        let sim = LogSim {
            range_noise_m: 0.0,
            ..LogSim::hokuyo()
        };
        let mut out = Vec::new();
        let pose = Pose2::new(2.0, 1.5, 0.0);
        sim.write(&mut out, &Walls::ring(), [pose, pose], |_| false, 1)
            .unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().filter(|l| l.starts_with("ROBOTLASER1")).collect();
        assert_eq!(lines.len(), 2);
        let fields: Vec<&str> = lines[0].split_whitespace().collect();
        assert_eq!(fields[8], "1081");
        // Beam 540 looks straight ahead: 10 m to the east wall.
        assert_eq!(fields[9 + 540], "10.000");
    }
}
