//! Marks the build with `cfg(shared_data)` when `PIROUETTE_SHARED` names the
//! shared evaluation data, so that the tests reading it run there and are
//! ignored (with their reason) elsewhere instead of passing without a check;
//! and names the commit the build comes from (`PIROUETTE_COMMIT`, with
//! `-modified` when the sources in the checkout differ from it), which
//! `--version` and the scoreboard show.
use std::process::Command;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(shared_data)");
    println!("cargo::rerun-if-env-changed=PIROUETTE_SHARED");
    if std::env::var_os("PIROUETTE_SHARED").is_some_and(|v| !v.is_empty()) {
        println!("cargo::rustc-cfg=shared_data");
    }
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    // Rerun on a commit (HEAD, or the branch it names, moves) and on an
    // edit of the sources; only paths that exist, or cargo reruns always.
    let mut watched = vec![
        "src".to_string(),
        "crates".into(),
        "Cargo.toml".into(),
        "Cargo.lock".into(),
    ];
    for (flag, names) in [
        ("--git-dir", &["HEAD"][..]),
        ("--git-common-dir", &["refs/heads", "packed-refs"][..]),
    ] {
        if let Some(dir) = git(&["rev-parse", flag]) {
            watched.extend(names.iter().map(|n| format!("{dir}/{n}")));
        }
    }
    for path in watched.iter().filter(|p| std::path::Path::new(p).exists()) {
        println!("cargo::rerun-if-changed={path}");
    }
    let commit = match git(&["rev-parse", "--short=7", "HEAD"]) {
        Some(hash) if !hash.is_empty() => {
            // Changes to what the build is made of, not to docs or CI.
            let modified = git(&[
                "status",
                "--porcelain",
                "--untracked-files=no",
                "--",
                "src",
                "crates",
                "Cargo.toml",
                "Cargo.lock",
                "build.rs",
            ])
            .is_some_and(|s| !s.is_empty());
            if modified {
                format!("{hash}-modified")
            } else {
                hash
            }
        }
        _ => "unknown".into(),
    };
    println!("cargo::rustc-env=PIROUETTE_COMMIT={commit}");
}
