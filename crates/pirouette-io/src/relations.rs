//! Text trajectories and relations: TUM trajectories (`t x y z qx qy qz
//! qw`, planar part read) and the SLAM benchmark's relation files (`t1 t2
//! x y z roll pitch yaw`).

use crate::IoError;
use pirouette_geom::Pose2;
use std::path::Path;

/// The most lines a trajectory or relations file may hold.
pub const MAX_TEXT_ROWS: usize = 50_000_000;

/// One timestamped planar pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedPose {
    /// Time, seconds.
    pub t: f64,
    /// The pose (heading from the quaternion's yaw).
    pub pose: Pose2,
}

/// One relation: the true pose of the scan at `t2` in the frame of the
/// scan at `t1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relation {
    /// The first scan's time, seconds.
    pub t1: f64,
    /// The second scan's time, seconds.
    pub t2: f64,
    /// The second pose in the first's frame (yaw as heading).
    pub pose: Pose2,
}

/// The numeric rows of a whitespace-separated text file, `#` lines and
/// blank lines skipped; every row must have at least `columns` finite
/// numbers.
pub(crate) fn rows(path: &Path, columns: usize, what: &str) -> Result<Vec<(usize, Vec<f64>)>, IoError> {
    let text = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    let text = std::str::from_utf8(&text).map_err(|_| IoError::invalid(path, "not text (invalid UTF-8)"))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if out.len() >= MAX_TEXT_ROWS {
            return Err(IoError::invalid(path, format!("more than {MAX_TEXT_ROWS} rows")));
        }
        let bad = |problem: String| IoError::Line {
            path: path.to_owned(),
            line: i + 1,
            problem,
        };
        let fields: Vec<&str> = line.split_ascii_whitespace().collect();
        if fields.len() < columns {
            return Err(bad(format!(
                "{} fields where a {what} line has {columns}",
                fields.len()
            )));
        }
        let values = fields[..columns]
            .iter()
            .map(|f| match f.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(bad(format!("`{f}` is not a finite number"))),
            })
            .collect::<Result<Vec<f64>, IoError>>()?;
        out.push((i + 1, values));
    }
    Ok(out)
}

/// The quaternion `qx qy qz qw` of a TUM row (columns 4-7) as written,
/// and its length, refused where it is far from a rotation's (a file
/// whose columns are in another order).
pub(crate) fn quaternion(path: &Path, line: usize, v: &[f64]) -> Result<[f64; 4], IoError> {
    let q = [v[4], v[5], v[6], v[7]];
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    if !(0.5..=2.0).contains(&norm) {
        return Err(IoError::Line {
            path: path.to_owned(),
            line,
            problem: format!("the quaternion's length {norm} is not 1"),
        });
    }
    Ok(q)
}

/// Reads a TUM trajectory: its planar poses, in file order.
pub fn read_tum(path: &Path) -> Result<Vec<StampedPose>, IoError> {
    rows(path, 8, "TUM")?
        .into_iter()
        .map(|(line, v)| {
            let [qx, qy, qz, qw] = quaternion(path, line, &v)?;
            let yaw = (2.0 * (qw * qz + qx * qy)).atan2(1.0 - 2.0 * (qy * qy + qz * qz));
            Ok(StampedPose {
                t: v[0],
                pose: Pose2::new(v[1], v[2], yaw),
            })
        })
        .collect()
}

/// Reads a relations file.
pub fn read_relations(path: &Path) -> Result<Vec<Relation>, IoError> {
    Ok(rows(path, 8, "relation")?
        .into_iter()
        .map(|(_, v)| Relation {
            t1: v[0],
            t2: v[1],
            pose: Pose2::new(v[2], v[3], v[7]),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tum_and_relation_lines_read_their_planar_part() {
        let dir = tempfile::tempdir().unwrap();
        let tum = dir.path().join("poses.tum");
        let half = 0.3f64;
        std::fs::write(
            &tum,
            format!(
                "# t x y z qx qy qz qw\n1.5 1 2 0 0 0 {} {}\n",
                half.sin(),
                half.cos()
            ),
        )
        .unwrap();
        let p = read_tum(&tum).unwrap();
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].t, 1.5);
        assert!((p[0].pose.theta - 0.6).abs() < 1e-12);
        let rel = dir.path().join("r.relations");
        std::fs::write(&rel, "10 11 0.5 -0.1 0 0 0 0.25\n\n").unwrap();
        let r = read_relations(&rel).unwrap();
        assert_eq!(
            r,
            vec![Relation {
                t1: 10.0,
                t2: 11.0,
                pose: Pose2::new(0.5, -0.1, 0.25)
            }]
        );
    }

    #[test]
    fn bad_lines_name_the_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("bad.tum");
        for (text, says) in [
            ("1 2 3\n", "fields"),
            ("1 2 3 0 0 0 0 nan\n", "finite"),
            ("1 2 3 0 0 0 0 0\n", "quaternion"),
        ] {
            std::fs::write(&f, text).unwrap();
            let e = read_tum(&f).unwrap_err().to_string();
            assert!(e.contains("bad.tum:1") && e.contains(says), "{e}");
        }
    }
}
