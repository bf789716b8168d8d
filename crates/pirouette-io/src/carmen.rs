//! CARMEN laser logs: a streaming reader of `FLASER` and `ROBOTLASER1`
//! scans with the raw odometry between them.
//!
//! A log is read one line at a time; only the scan being assembled is
//! held, so memory does not grow with the log. The raw odometry comes in
//! one of two conventions ([`OdometrySource`]), told apart per step:
//! - **`ODOM` lines** (logs published with a corrected trajectory, whose
//!   `FLASER` pose fields hold it): the increment between scans `k` and
//!   `k + 1` is `P_k⁻¹ · O`, `P_k` being scan `k`'s recorded pose and `O`
//!   the last `ODOM` pose before scan `k + 1` (a mapper restarts the
//!   odometry from each corrected pose). Where no `ODOM` line after scan
//!   `k` moved away from `P_k`, the step has none.
//! - **The `FLASER` odometry fields** (raw logs, written as recorded and
//!   without `ODOM` lines): the increment is `Q_k⁻¹ · Q_{k+1}`, `Q` being
//!   the `odom_x odom_y odom_theta` triple; where it did not move, the
//!   step has none.
//!
//! Once a log has given an `ODOM` line, its `FLASER` fields are never read
//! as odometry (they may be a corrected trajectory). A step without
//! odometry says so ([`LaserScan::odometry`] is `None`).
//! Other lines (`NEFF`, `PARAM`, `SYNC`, `RLASER`, `TRUEPOS`, comments)
//! are skipped.

use crate::IoError;
use pirouette_geom::Pose2;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// The most beams a scan may have.
pub const MAX_BEAMS: usize = 10_000;

/// The longest line read, bytes (a scan of [`MAX_BEAMS`] beams with
/// remissions fits comfortably).
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Ranges at or beyond this, metres, are no return in an `FLASER` line,
/// which does not give its scanner's maximum (scanners report 50 m,
/// 81.83 m or 81.91 m for no return; no indoor laser measures this far).
pub const FLASER_NO_RETURN_M: f32 = 49.9;

/// One laser scan of a log.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserScan {
    /// Its position among the log's laser lines, from 0.
    pub scan: usize,
    /// Its line in the file, from 1 (0 for a scan read from a bag).
    pub line: usize,
    /// Its timestamp, seconds (damaged in some logs: order scans by
    /// [`LaserScan::scan`], not by time).
    pub t: f64,
    /// Bearing of the first beam, radians (counter-clockwise, 0 ahead).
    pub first_bearing_rad: f64,
    /// Angle between neighbouring beams, radians.
    pub beam_step_rad: f64,
    /// The ranges, metres, from the first beam on; `+∞` where the beam
    /// had no return (the scanner's maximum), NaN where the reading is not
    /// a range (negative).
    pub ranges_m: Vec<f32>,
    /// The pose of the scan the log records (for logs published with a
    /// corrected trajectory, that trajectory), `world_from_robot`.
    pub recorded: Pose2,
    /// Raw odometry since the previous scan, in the previous scan's
    /// frame; `None` for the first scan and where the log holds none.
    pub odometry: Option<Pose2>,
    /// Where the odometry came from (`None` with it).
    pub odometry_source: Option<OdometrySource>,
}

/// Where a step's odometry was read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OdometrySource {
    /// `ODOM` lines after a scan's recorded (corrected) pose.
    OdomLines,
    /// The odometry fields of consecutive `FLASER` lines (a raw log).
    LaserFields,
    /// A ROS bag's odometry messages or `/tf` transforms, at the scans'
    /// stamps.
    Bag,
}

impl OdometrySource {
    /// How a summary names it.
    pub fn describe(self) -> &'static str {
        match self {
            OdometrySource::OdomLines => "ODOM lines after corrected FLASER poses",
            OdometrySource::LaserFields => "the FLASER odometry fields (a raw log)",
            OdometrySource::Bag => "the bag's odometry at each scan's stamp",
        }
    }
}

/// Reads the laser scans of a CARMEN log one at a time.
pub struct CarmenReader<R> {
    path: PathBuf,
    input: R,
    line: usize,
    buf: Vec<u8>,
    scans: usize,
    /// The previous scan's recorded pose.
    previous: Option<Pose2>,
    /// The last odometry pose since it.
    odom: Option<Pose2>,
    /// Whether the log has given an `ODOM` line.
    odom_lines: bool,
    /// The previous scan's odometry fields (`FLASER`; `None` for others).
    previous_fields: Option<Pose2>,
    /// The laser's offset ahead of the robot centre, metres
    /// (`PARAM robot_frontlaser_offset`).
    laser_offset_m: f64,
    failed: bool,
}

impl CarmenReader<BufReader<std::fs::File>> {
    /// Opens a log file.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
        if file.metadata().map_err(|e| IoError::io(path, e))?.is_dir() {
            return Err(IoError::invalid(path, "is a folder, not a laser log"));
        }
        Ok(Self::new(path, BufReader::new(file)))
    }
}

impl<R: BufRead> CarmenReader<R> {
    /// A reader of `input`, named `path` in its errors.
    pub fn new(path: &Path, input: R) -> Self {
        Self {
            path: path.to_owned(),
            input,
            line: 0,
            buf: Vec::new(),
            scans: 0,
            previous: None,
            odom: None,
            odom_lines: false,
            previous_fields: None,
            laser_offset_m: 0.0,
            failed: false,
        }
    }

    fn bad(&self, problem: impl Into<String>) -> IoError {
        IoError::Line {
            path: self.path.clone(),
            line: self.line,
            problem: problem.into(),
        }
    }

    /// The next line, without its end; `None` at the end of the file.
    fn next_line(&mut self) -> Result<Option<String>, IoError> {
        self.buf.clear();
        let limit = MAX_LINE_BYTES as u64 + 1;
        let n = (&mut self.input)
            .take(limit)
            .read_until(b'\n', &mut self.buf)
            .map_err(|e| IoError::io(&self.path, e))?;
        if n == 0 {
            return Ok(None);
        }
        self.line += 1;
        if self.buf.len() > MAX_LINE_BYTES {
            return Err(self.bad(format!("a line longer than {MAX_LINE_BYTES} bytes")));
        }
        match std::str::from_utf8(&self.buf) {
            Ok(s) => Ok(Some(s.trim_end_matches(['\n', '\r']).to_owned())),
            Err(_) => Err(self.bad("not text (invalid UTF-8)")),
        }
    }

    /// The next scan, or `None` at the end of the log.
    fn next_scan(&mut self) -> Result<Option<LaserScan>, IoError> {
        while let Some(text) = self.next_line()? {
            let mut fields = text.split_ascii_whitespace();
            let Some(kind) = fields.next() else { continue };
            let fields: Vec<&str> = fields.collect();
            match kind {
                "FLASER" => return self.flaser(&fields).map(Some),
                "ROBOTLASER1" => return self.robotlaser(&fields).map(Some),
                "ODOM" => {
                    let v = self.numbers(&fields, 3, "ODOM")?;
                    self.odom = Some(self.pose(v[0], v[1], v[2])?);
                    self.odom_lines = true;
                }
                "PARAM" if fields.first() == Some(&"robot_frontlaser_offset") => {
                    let v = self.numbers(&fields[1..], 1, "PARAM robot_frontlaser_offset")?;
                    if !(v[0].is_finite() && v[0].abs() <= 10.0) {
                        return Err(self.bad(format!("laser offset {} m is not within ±10 m", v[0])));
                    }
                    self.laser_offset_m = v[0];
                }
                _ => {}
            }
        }
        Ok(None)
    }

    /// The first `count` fields as finite numbers.
    fn numbers(&self, fields: &[&str], count: usize, what: &str) -> Result<Vec<f64>, IoError> {
        if fields.len() < count {
            return Err(self.bad(format!(
                "{what}: {} fields, expected at least {count}",
                fields.len()
            )));
        }
        fields[..count]
            .iter()
            .map(|f| match f.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(self.bad(format!("{what}: `{f}` is not a finite number"))),
            })
            .collect()
    }

    fn pose(&self, x: f64, y: f64, theta: f64) -> Result<Pose2, IoError> {
        // A building is not 1000 km across.
        if x.abs() > 1e6 || y.abs() > 1e6 || theta.abs() > 1e3 {
            return Err(self.bad(format!("pose ({x}, {y}, {theta}) is out of range")));
        }
        Ok(Pose2::new(x, y, theta))
    }

    /// The beam count of a line, checked.
    fn beam_count(&self, field: Option<&&str>, what: &str) -> Result<usize, IoError> {
        match field.and_then(|f| f.parse::<usize>().ok()) {
            Some(n) if (2..=MAX_BEAMS).contains(&n) => Ok(n),
            _ => Err(self.bad(format!("{what}: the beam count must be 2 to {MAX_BEAMS}"))),
        }
    }

    /// `FLASER n r1 .. rn x y theta odom_x odom_y odom_theta timestamp ...`:
    /// beams over 180° from the right, their layout from the count alone.
    fn flaser(&mut self, fields: &[&str]) -> Result<LaserScan, IoError> {
        let n = self.beam_count(fields.first(), "FLASER")?;
        let v = self.numbers(&fields[1..], n + 7, "FLASER")?;
        let pi = std::f64::consts::PI;
        // Odd counts end on ±90°; even ones are 180°/n apart from −90°.
        let step = if n % 2 == 1 {
            pi / (n - 1) as f64
        } else {
            pi / n as f64
        };
        let ranges = v[..n]
            .iter()
            .map(|&r| range(r, f64::from(FLASER_NO_RETURN_M)))
            .collect();
        let recorded = self.pose(v[n], v[n + 1], v[n + 2])?;
        let fields = self.pose(v[n + 3], v[n + 4], v[n + 5])?;
        self.finish_scan(-pi / 2.0, step, ranges, recorded, Some(fields), v[n + 6])
    }

    /// `ROBOTLASER1 type start fov resolution max_range accuracy
    /// remission_mode n r1 .. rn m e1 .. em laser_x laser_y laser_theta
    /// robot_x robot_y robot_theta tv rv forward_safety side_safety
    /// turn_axis timestamp ...`.
    fn robotlaser(&mut self, fields: &[&str]) -> Result<LaserScan, IoError> {
        let head = self.numbers(fields, 7, "ROBOTLASER1")?;
        let (start, fov, resolution, max_range) = (head[1], head[2], head[3], head[4]);
        let n = self.beam_count(fields.get(7), "ROBOTLASER1")?;
        let ranges_at = 8;
        let rest = fields.get(ranges_at + n..).unwrap_or(&[]);
        let m = match rest.first().and_then(|f| f.parse::<usize>().ok()) {
            Some(m) if m <= MAX_BEAMS => m,
            _ => return Err(self.bad("ROBOTLASER1: the remission count is missing or too large")),
        };
        let v = self.numbers(&fields[ranges_at..], n, "ROBOTLASER1")?;
        let tail = self.numbers(rest.get(1 + m..).unwrap_or(&[]), 12, "ROBOTLASER1")?;
        let step_ok =
            resolution.is_finite() && resolution > 0.0 && resolution * n as f64 <= 2.0 * fov.max(resolution);
        if !(step_ok && start.abs() <= 2.0 * std::f64::consts::PI && fov > 0.0 && max_range > 0.0) {
            return Err(self.bad(format!(
                "ROBOTLASER1: start {start}, field of view {fov}, resolution {resolution} or maximum range {max_range} is not a scanner's"
            )));
        }
        let ranges = v.iter().map(|&r| range(r, max_range)).collect();
        let recorded = self.pose(tail[3], tail[4], tail[5])?;
        self.finish_scan(start, resolution, ranges, recorded, None, tail[11])
    }

    fn finish_scan(
        &mut self,
        first_bearing_rad: f64,
        beam_step_rad: f64,
        mut ranges_m: Vec<f32>,
        recorded: Pose2,
        fields: Option<Pose2>,
        t: f64,
    ) -> Result<LaserScan, IoError> {
        // A laser ahead of the centre: its ranges start there, which the
        // profile's centre-based ranges fold in.
        if self.laser_offset_m != 0.0 {
            for (i, r) in ranges_m.iter_mut().enumerate() {
                if r.is_finite() {
                    let b = first_bearing_rad + i as f64 * beam_step_rad;
                    let (x, y) = (self.laser_offset_m + *r as f64 * b.cos(), *r as f64 * b.sin());
                    *r = x.hypot(y) as f32;
                }
            }
        }
        let (odometry, odometry_source) = match (self.previous, self.odom, self.previous_fields, fields) {
            // The odometry only repeating the scan's pose: none recorded.
            (Some(p), Some(o), _, _) if o != p => (Some(p.between(&o)), Some(OdometrySource::OdomLines)),
            (_, _, Some(a), Some(b)) if !self.odom_lines && a != b => {
                (Some(a.between(&b)), Some(OdometrySource::LaserFields))
            }
            _ => (None, None),
        };
        let scan = LaserScan {
            scan: self.scans,
            line: self.line,
            t,
            first_bearing_rad,
            beam_step_rad,
            ranges_m,
            recorded,
            odometry,
            odometry_source,
        };
        self.scans += 1;
        self.previous = Some(recorded);
        self.previous_fields = fields;
        self.odom = None;
        Ok(scan)
    }
}

/// A reading as a range: `+∞` at or beyond `no_return_m`, NaN below 0.
fn range(r: f64, no_return_m: f64) -> f32 {
    if r >= no_return_m {
        f32::INFINITY
    } else if r < 0.0 {
        f32::NAN
    } else {
        r as f32
    }
}

impl<R: BufRead> Iterator for CarmenReader<R> {
    type Item = Result<LaserScan, IoError>;

    /// The next scan; after an error, `None`.
    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let next = self.next_scan().transpose();
        if matches!(next, Some(Err(_))) {
            self.failed = true;
        }
        next
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Vec<LaserScan>, IoError> {
        CarmenReader::new(Path::new("test.log"), text.as_bytes()).collect()
    }

    fn flaser(ranges: &[f64], pose: [f64; 3], t: f64) -> String {
        let r: Vec<String> = ranges.iter().map(|r| r.to_string()).collect();
        let [x, y, th] = pose;
        format!(
            "FLASER {} {} {x} {y} {th} {x} {y} {th} {t} host {t}\n",
            ranges.len(),
            r.join(" ")
        )
    }

    #[test]
    fn beams_poses_and_odometry_are_read() {
        let mut log = String::from("# comment\nPARAM robot_frontlaser_offset 0.0 nohost 0\n");
        log += &flaser(&[1.0, 2.0, 81.83, -1.0], [1.0, 2.0, 0.5], 10.0);
        log += "ODOM 1 2 0.5 0 0 0 0 host 0\nNEFF 15\n";
        // The raw odometry moves 1 m along x in the world, turns 0.1 rad.
        log += "ODOM 2 2 0.6 0 0 0 10.5 host 10.5\n";
        log += &flaser(&[1.0, 1.0, 1.0, 1.0], [2.1, 2.0, 0.6], 11.0);
        // Only the pose repeated: no odometry for this step.
        log += "ODOM 2.1 2 0.6 0 0 0 0 host 0\n";
        log += &flaser(&[1.0, 1.0, 1.0, 1.0], [3.0, 2.0, 0.6], 12.0);
        let scans = read(&log).unwrap();
        assert_eq!(scans.len(), 3);
        let s = &scans[0];
        assert_eq!((s.scan, s.line, s.t), (0, 3, 10.0));
        // Four beams: 45° apart from −90°.
        assert!((s.first_bearing_rad + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((s.beam_step_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert_eq!(&s.ranges_m[..2], &[1.0, 2.0]);
        assert_eq!(s.ranges_m[2], f32::INFINITY);
        assert!(s.ranges_m[3].is_nan());
        assert_eq!(s.recorded, Pose2::new(1.0, 2.0, 0.5));
        assert_eq!(s.odometry, None);
        let odo = scans[1].odometry.unwrap();
        let expect = Pose2::new(1.0, 2.0, 0.5).between(&Pose2::new(2.0, 2.0, 0.6));
        assert!((odo.x - expect.x).abs() < 1e-12 && (odo.y - expect.y).abs() < 1e-12);
        assert!((odo.theta - 0.1).abs() < 1e-12);
        assert_eq!(scans[2].odometry, None);
    }

    #[test]
    fn a_raw_log_carries_its_odometry_in_the_laser_fields() {
        // No ODOM lines; the odometry triple differs from the pose triple.
        let line = |pose: [f64; 3], odom: [f64; 3], t: f64| {
            format!(
                "FLASER 2 1 1 {} {} {} {} {} {} {t} host {t}\n",
                pose[0], pose[1], pose[2], odom[0], odom[1], odom[2]
            )
        };
        let log = line([5.0, 5.0, 0.0], [1.0, 0.0, 0.0], 0.0)
            + &line([5.0, 5.0, 0.0], [1.0, 1.0, 0.5], 1.0)
            + &line([5.0, 5.0, 0.0], [1.0, 1.0, 0.5], 2.0);
        let scans = read(&log).unwrap();
        let odo = scans[1].odometry.unwrap();
        let expect = Pose2::new(1.0, 0.0, 0.0).between(&Pose2::new(1.0, 1.0, 0.5));
        assert!((odo.x - expect.x).abs() < 1e-12 && (odo.y - expect.y).abs() < 1e-12);
        assert!((odo.theta - 0.5).abs() < 1e-12);
        assert_eq!(scans[1].odometry_source, Some(OdometrySource::LaserFields));
        // Standing still: no odometry for the step.
        assert_eq!(scans[2].odometry, None);
        // Once ODOM lines appear, the fields are not odometry.
        let log = String::from("ODOM 0 0 0 0 0 0 0 h 0\n")
            + &line([0.0; 3], [0.0; 3], 0.0)
            + &line([1.0, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0);
        assert_eq!(read(&log).unwrap()[1].odometry, None);
    }

    #[test]
    fn odd_beam_counts_end_on_both_sides() {
        let scans = read(&flaser(&[1.0; 181], [0.0; 3], 0.0)).unwrap();
        let s = &scans[0];
        let last = s.first_bearing_rad + 180.0 * s.beam_step_rad;
        assert!((last - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn a_robotlaser_line_gives_its_own_layout_and_maximum() {
        let line = "ROBOTLASER1 0 -1.5 3.0 1.0 4.0 0.01 0 4 1.0 4.0 5.0 2.5 0 \
                    0.1 0.2 0.3 1.0 2.0 0.3 0 0 0 0 0 7.5 host 7.5\n";
        let scans = read(line).unwrap();
        let s = &scans[0];
        assert_eq!((s.first_bearing_rad, s.beam_step_rad, s.t), (-1.5, 1.0, 7.5));
        assert_eq!(s.ranges_m[0], 1.0);
        assert_eq!(&s.ranges_m[1..3], &[f32::INFINITY, f32::INFINITY]);
        assert_eq!(s.ranges_m[3], 2.5);
        assert_eq!(s.recorded, Pose2::new(1.0, 2.0, 0.3));
    }

    #[test]
    fn a_laser_offset_moves_ranges_to_the_centre() {
        let log = String::from("PARAM robot_frontlaser_offset 0.5 nohost 0\n")
            + &flaser(&[1.0, 1.0], [0.0; 3], 0.0);
        let s = &read(&log).unwrap()[0];
        // The beam at −90° from a laser 0.5 m ahead: √(0.5² + 1²) from the centre.
        assert!((s.ranges_m[0] - 1.25f32.sqrt()).abs() < 1e-6);
    }

    #[test]
    fn malformed_lines_name_the_file_and_line() {
        let cases = [
            ("FLASER 3 1 2\n", "fields"),
            ("FLASER 0\n", "beam count"),
            ("FLASER 99999999 1\n", "beam count"),
            ("ODOM 1 nan 0 0 0 0 0 h 0\n", "not a finite number"),
            ("ODOM 1e300 0 0 0 0 0 0 h 0\n", "out of range"),
            ("\nFLASER 2 1 x 0 0 0 0 0 0 0 h 0\n", "`x`"),
            ("PARAM robot_frontlaser_offset 1e9 h 0\n", "offset"),
            (
                "ROBOTLASER1 0 -1.5 3.0 1.0 4.0 0.01 0 2 1.0 1.0 99999999\n",
                "remission",
            ),
            (
                "ROBOTLASER1 0 -1.5 3.0 -1.0 4.0 0.01 0 2 1 1 0 0 0 0 0 0 0 0 0 0 0 0 0 h 0\n",
                "scanner",
            ),
        ];
        for (text, says) in cases {
            let err = read(text).unwrap_err().to_string();
            assert!(err.starts_with("test.log:"), "{err}");
            assert!(err.contains(says), "{text:?}: {err}");
        }
        let long = "#".repeat(MAX_LINE_BYTES + 10);
        assert!(read(&long).unwrap_err().to_string().contains("longer"));
        let binary: Result<Vec<_>, _> =
            CarmenReader::new(Path::new("test.log"), &b"FLASER \xff\xfe"[..]).collect();
        assert!(binary.unwrap_err().to_string().contains("UTF-8"));
    }
}
