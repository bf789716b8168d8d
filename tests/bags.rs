//! ROS bags: a simulated recording written as ROS 1 (every compression),
//! MCAP and sqlite3 bags maps to the same poses from each, the laser's
//! mount taken off; the shared benchmark bags in every format; bad bags
//! refused with the file and the topic or offset named.

use crate::util::{pirouette, ring_path, shared};
use pirouette::geom::Pose2;
use pirouette::io::bag::wire::{encode, FramePose, ScanMsg, Wire};
use pirouette::io::bag::write::{
    convert, write_mcap, write_ros1, write_sqlite, BagFormat, OutMessage, Ros1Compression,
};
use pirouette::io::bag::Connection;
use pirouette::io::{open_laser_log, BagOptions};
use pirouette::laser::{register_log, LaserConfig, RegisteredLog};
use pirouette::sim::Walls;
use std::path::{Path, PathBuf};

/// The laser 0.2 m ahead of the robot's centre and 0.05 m left, turned 5°.
fn mount() -> Pose2 {
    Pose2::from_deg(0.2, 0.05, 5.0)
}

/// Once round the ring corridor ([`Walls::ring`]) in 5 cm steps (most
/// left out by the motion filter), turning 10° at a time at the corners.
fn path() -> Vec<Pose2> {
    ring_path(4, 0.05, 9, 10.0)
}

/// The recording's messages in `wire`: per pose a scan from the mounted
/// laser (361 beams over 180°, a reading of 0 and one NaN among them) and,
/// 10 ms before and after, odometry that overshoots moves by 3 % and turns
/// by 2 %; the mount on /tf_static first.
fn recording(wire: Wire) -> (Vec<Connection>, Vec<OutMessage>) {
    let walls = Walls::ring();
    let connections = vec![
        Connection::new("/tf_static".into(), "tf2_msgs/TFMessage"),
        Connection::new("/odom".into(), "nav_msgs/Odometry"),
        Connection::new("/scan".into(), "sensor_msgs/LaserScan"),
    ];
    let t0 = 1_000_000_000_000u64;
    let frame = |t: u64, parent: &str, child: &str, pose: Pose2| FramePose {
        stamp_ns: t as i64,
        parent: parent.into(),
        child: child.into(),
        pose,
    };
    let mut out = vec![OutMessage {
        connection: 0,
        time_ns: t0,
        data: encode::transforms(&[frame(t0, "base_link", "laser", mount())], wire),
    }];
    let truth = path();
    let mut odom = truth[0];
    let mut odom_at = |k: usize| {
        if k > 0 {
            let s = truth[k - 1].between(&truth[k]);
            odom = odom * Pose2::new(s.x * 1.03, s.y * 1.03, s.theta * 1.02);
        }
        odom
    };
    let n = 361;
    for (k, p) in truth.iter().enumerate() {
        let t = t0 + 100_000_000 + k as u64 * 100_000_000;
        let o = odom_at(k);
        out.push(OutMessage {
            connection: 1,
            time_ns: t - 10_000_000,
            data: encode::odometry(&frame(t - 10_000_000, "odom", "base_link", o), wire),
        });
        let laser = *p * mount();
        let step = std::f64::consts::PI / (n - 1) as f64;
        let ranges: Vec<f32> = (0..n)
            .map(|i| match i {
                7 => 0.0,
                8 => f32::NAN,
                _ => {
                    let b = laser.theta - std::f64::consts::FRAC_PI_2 + i as f64 * step;
                    walls
                        .cast([laser.x, laser.y], [b.cos(), b.sin()])
                        .map_or(f32::INFINITY, |r| r as f32)
                }
            })
            .collect();
        let scan = ScanMsg {
            stamp_ns: t as i64,
            frame: "laser".into(),
            angle_min: -std::f32::consts::FRAC_PI_2,
            angle_max: std::f32::consts::FRAC_PI_2,
            angle_increment: step as f32,
            range_min: 0.05,
            range_max: 30.0,
            ranges,
        };
        out.push(OutMessage {
            connection: 2,
            time_ns: t,
            data: encode::laser_scan(&scan, wire),
        });
        // The odometry just after the scan (interpolation brackets it).
        let o2 = o;
        out.push(OutMessage {
            connection: 1,
            time_ns: t + 10_000_000,
            data: encode::odometry(&frame(t + 10_000_000, "odom", "base_link", o2), wire),
        });
    }
    (connections, out)
}

fn map(bag: &Path) -> RegisteredLog {
    register_log(bag, &LaserConfig::default(), &BagOptions::default(), &|| {}).expect("the bag maps")
}

/// Every scan's pose (registered or left out by the motion filter), by scan.
fn all_poses(r: &RegisteredLog) -> Vec<(usize, Pose2)> {
    r.every_scan().into_iter().map(|(k, _, p)| (k, p)).collect()
}

#[test]
fn one_recording_maps_alike_from_every_bag_format_and_the_mount_comes_off() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let (connections, ros1) = recording(Wire::Ros1);
    let (_, cdr) = recording(Wire::Cdr);
    let mut bags: Vec<PathBuf> = Vec::new();
    for c in [Ros1Compression::None, Ros1Compression::Bz2, Ros1Compression::Lz4] {
        let p = dir.path().join(format!("sim-{c:?}.bag"));
        // Small chunks: messages cross chunk boundaries.
        write_ros1(&p, &connections, ros1.clone(), c, 20_000).expect("a ROS 1 bag");
        bags.push(p);
    }
    let mcap = dir.path().join("sim-mcap");
    write_mcap(&mcap, &connections, cdr.clone()).expect("an MCAP bag");
    let db3 = dir.path().join("sim-db3");
    write_sqlite(&db3, &connections, cdr).expect("a sqlite3 bag");
    bags.push(mcap.clone());
    bags.push(db3.clone());
    // The storage files themselves read as well as their folders.
    bags.push(mcap.join("sim-mcap_0.mcap"));
    bags.push(db3.join("sim-db3_0.db3"));

    let reference = map(&bags[0]);
    let poses = all_poses(&reference);
    let truth = path();
    assert_eq!(poses.len(), truth.len(), "a pose per scan");
    assert!(
        reference.skipped.len() > truth.len() / 3,
        "every other 5 cm step is left to the motion filter: {} of {} skipped",
        reference.skipped.len(),
        truth.len()
    );
    let m = reference.info.mount.between(&mount());
    assert!(
        m.translation().norm() < 1e-9 && m.theta.abs() < 1e-9,
        "mount {:?}",
        reference.info.mount
    );
    // Against the truth, in the first pose's frame: the mount taken off.
    let first = truth[0];
    let mut worst: f64 = 0.0;
    for ((_, est), t) in poses.iter().zip(&truth) {
        let want = first.between(t);
        worst = worst.max(est.between(&want).translation().norm());
    }
    assert!(worst < 0.05, "worst position error {worst} m");
    for bag in &bags[1..] {
        let other = map(bag);
        assert_eq!(all_poses(&other), poses, "{} maps otherwise", bag.display());
    }
}

#[test]
fn bad_bags_name_the_file_and_what_is_wrong() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let (connections, messages) = recording(Wire::Ros1);
    let good = dir.path().join("good.bag");
    write_ros1(
        &good,
        &connections,
        messages.clone(),
        Ros1Compression::Bz2,
        50_000,
    )
    .expect("a bag");
    let err = |path: &Path, options: &BagOptions| -> String {
        let run = || -> Result<usize, pirouette::io::IoError> {
            let mut n = 0;
            for s in open_laser_log(path, options)? {
                s?;
                n += 1;
            }
            Ok(n)
        };
        run().expect_err("refused").to_string()
    };
    // A bag of one chunk, its bz2 stream damaged: nothing can be read.
    let one = dir.path().join("one.bag");
    write_ros1(
        &one,
        &connections,
        messages.clone(),
        Ros1Compression::Bz2,
        1 << 30,
    )
    .expect("a bag");
    let mut damaged = std::fs::read(&one).expect("the bag");
    let at = 4096 + 13 + 200;
    for b in &mut damaged[at..at + 64] {
        *b ^= 0x5a;
    }
    std::fs::write(&one, &damaged).expect("write");
    let e = err(&one, &BagOptions::default());
    assert!(
        e.contains("one.bag") && e.contains("no chunk of the bag can be read"),
        "{e}"
    );
    // The wrong type on the chosen topic, and a topic not there.
    let scan_on = |t: &str| BagOptions {
        scan_topic: Some(t.into()),
        odom_topic: None,
    };
    let e = err(&good, &scan_on("/odom"));
    assert!(e.contains("/odom") && e.contains("nav_msgs/Odometry"), "{e}");
    let e = err(&good, &scan_on("/front_scan"));
    assert!(e.contains("no topic `/front_scan`") && e.contains("/scan"), "{e}");
    // Two scan topics: the user must choose.
    let mut two = connections.clone();
    two.push(Connection::new("/rear_scan".into(), "sensor_msgs/LaserScan"));
    let twice = dir.path().join("two.bag");
    write_ros1(&twice, &two, messages.clone(), Ros1Compression::None, 50_000).expect("a bag");
    let e = err(&twice, &BagOptions::default());
    assert!(e.contains("--scan-topic") && e.contains("/rear_scan"), "{e}");
    // A scan whose ranges and angles disagree.
    let mut wrong = messages.clone();
    let i = wrong.iter().position(|m| m.connection == 2).expect("a scan");
    wrong[i].data = encode::laser_scan(
        &ScanMsg {
            stamp_ns: 1_000_100_000_000,
            frame: "laser".into(),
            angle_min: -1.0,
            angle_max: 1.0,
            angle_increment: 0.5,
            range_min: 0.0,
            range_max: 10.0,
            ranges: vec![1.0; 40],
        },
        Wire::Ros1,
    );
    let odd = dir.path().join("odd.bag");
    write_ros1(&odd, &connections, wrong, Ros1Compression::None, 50_000).expect("a bag");
    let e = err(&odd, &BagOptions::default());
    assert!(
        e.contains("odd.bag") && e.contains("/scan") && e.contains("disagree"),
        "{e}"
    );
    // Not a bag at all, named .bag: read as CARMEN, which finds no scan.
    let text = dir.path().join("notes.bag");
    std::fs::write(&text, "hello\n").expect("write");
    let out = pirouette(&[
        "map",
        text.to_str().expect("utf-8"),
        "--out",
        dir.path().join("m").to_str().expect("utf-8"),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("notes.bag"));
}

/// A ROS 1 bag cut short, or with a damaged chunk, gives the scans it
/// holds; a warning names the byte, and `map` maps them.
#[test]
fn damaged_ros1_bags_give_what_they_hold_with_a_warning() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let (connections, messages) = recording(Wire::Ros1);
    let good = dir.path().join("good.bag");
    write_ros1(&good, &connections, messages, Ros1Compression::Bz2, 50_000).expect("a bag");
    let bytes = std::fs::read(&good).expect("the bag");
    let read = |path: &Path| {
        let mut log = open_laser_log(path, &BagOptions::default()).expect("the bag opens");
        let mut scans = 0;
        for s in &mut log {
            s.expect("a scan");
            scans += 1;
        }
        let pirouette::io::LaserLog::Bag(b) = log else {
            panic!("a bag")
        };
        (scans, b.info().warnings)
    };
    let (all, warnings) = read(&good);
    assert!(all > 100 && warnings.is_empty(), "{all} {warnings:?}");
    // Cut short in the middle of a chunk: the chunks before the cut.
    let cut = dir.path().join("cut.bag");
    let half = bytes.len() / 2;
    std::fs::write(&cut, &bytes[..half]).expect("write");
    let (n, warnings) = read(&cut);
    assert!(n > all / 4 && n < all, "{n} of {all} scans");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let w = &warnings[0];
    assert!(w.contains("cut.bag") && w.contains("cut short"), "{w}");
    let byte: usize = (w.split("at byte ").nth(1))
        .and_then(|r| r.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|b| b.parse().ok())
        .expect("the byte named");
    assert!(byte > 4096 && byte < half, "{w}");
    // A chunk whose bz2 stream is damaged: the others.
    let mut damaged = bytes.clone();
    let at = 4096 + 13 + 200;
    for b in &mut damaged[at..at + 64] {
        *b ^= 0x5a;
    }
    let bad = dir.path().join("damaged.bag");
    std::fs::write(&bad, &damaged).expect("write");
    let (n, warnings) = read(&bad);
    assert!(n > all / 2 && n < all, "{n} of {all} scans");
    assert!(
        warnings.len() == 1
            && warnings[0].contains("1 chunk(s) skipped")
            && warnings[0].contains("damaged.bag"),
        "{warnings:?}"
    );
    // `map` writes the poses of what was read, and says what it lost.
    let out = dir.path().join("map");
    let o = pirouette(&[
        "map",
        cut.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("warning:") && err.contains("cut short"), "{err}");
    assert!(out.join("poses.json").is_file());
}

#[test]
fn scans_stamped_backwards_are_skipped_and_counted() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let (connections, mut messages) = recording(Wire::Ros1);
    // The 21st scan's header stamp 5 s earlier than the 20th's.
    let k = (messages.iter().enumerate())
        .filter(|(_, m)| m.connection == 2)
        .nth(20)
        .map(|(i, _)| i)
        .expect("scans");
    let mut scan = pirouette::io::bag::wire::laser_scan(&messages[k].data, Wire::Ros1).expect("a scan");
    scan.stamp_ns -= 5_000_000_000;
    messages[k].data = encode::laser_scan(&scan, Wire::Ros1);
    let bag = dir.path().join("back.bag");
    write_ros1(&bag, &connections, messages, Ros1Compression::None, 50_000).expect("a bag");
    let r = map(&bag);
    assert_eq!(
        r.info.skipped,
        vec![("scans stamped before the previous scan".to_owned(), 1)]
    );
    assert!(all_poses(&r).iter().all(|(s, _)| *s != 20));
}

#[cfg_attr(not(shared_data), ignore = "needs the shared data: set PIROUETTE_SHARED")]
#[test]
fn a_benchmark_bag_gives_the_same_poses_in_every_format() {
    let src = shared().join("laser/benchmark/aces.bag");
    let dir = tempfile::tempdir().expect("temporary folder");
    let formats = [
        ("lz4.bag", BagFormat::Ros1(Ros1Compression::Lz4)),
        ("mcap", BagFormat::Mcap),
        ("db3", BagFormat::Sqlite),
    ];
    let out = |name: &str| dir.path().join(name);
    let tum = |bag: &Path, name: &str| -> String {
        let o = out(name);
        let run = pirouette(&[
            "map",
            bag.to_str().expect("utf-8"),
            "--out",
            o.to_str().expect("utf-8"),
        ]);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        std::fs::read_to_string(o.join("poses.tum")).expect("poses.tum")
    };
    // The first 150 s of the recording, as a ROS 1 bag and in each format.
    let first = out("first.bag");
    convert(&src, &first, BagFormat::Ros1(Ros1Compression::Bz2), Some(150.0)).expect("cut");
    let reference = tum(&first, "map-ros1");
    let scans = open_laser_log(&first, &BagOptions::default())
        .expect("a bag")
        .count();
    assert!(scans > 500, "{scans} scans");
    assert_eq!(reference.lines().count(), 1 + scans, "a pose per scan of the bag");
    for (name, format) in formats {
        let bag = out(name);
        convert(&first, &bag, format, None).expect("converted");
        assert_eq!(tum(&bag, &format!("map-{name}")), reference, "{name}");
    }
    // The relations metric on the map folder, as outside evaluation reads it.
    let rel = shared().join("laser/benchmark/aces.relations");
    let run = pirouette(&[
        "eval",
        "relations",
        out("map-ros1").to_str().expect("utf-8"),
        rel.to_str().expect("utf-8"),
        "--json",
    ]);
    assert!(run.status.success());
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).expect("JSON");
    assert_eq!(v["relations"], 1279);
    let used = v["used"].as_u64().expect("a count");
    assert!(
        used > 50 && used + v["unmatched"].as_u64().expect("a count") == 1279,
        "{v}"
    );
    let trans = v["trans_abs_m"].as_f64().expect("a number");
    assert!(trans < 0.06, "aces relations over the first 150 s: {trans} m");
}
