//! Marks the build with `cfg(shared_data)` when `PIROUETTE_SHARED` names the
//! shared evaluation data, so that the tests reading it run there and are
//! ignored (with their reason) elsewhere instead of passing without a check.
fn main() {
    println!("cargo::rustc-check-cfg=cfg(shared_data)");
    println!("cargo::rerun-if-env-changed=PIROUETTE_SHARED");
    if std::env::var_os("PIROUETTE_SHARED").is_some_and(|v| !v.is_empty()) {
        println!("cargo::rustc-cfg=shared_data");
    }
}
