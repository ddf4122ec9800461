//! Writes `analytic.rs` into OUT_DIR: `pcc_fs_fc_6`, the small-θ functions up to order 6,
//! which only the tests compile (the models call the orders they need, generated inline).

use std::path::PathBuf;

fn main() {
    // Rebuilt with the generator (a build dependency), so only this file is watched.
    println!("cargo:rerun-if-changed=build.rs");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let source = softcbf_codegen::emit::format_file(softcbf_codegen::analytic::emit(6));
    std::fs::write(out_dir.join("analytic.rs"), source).expect("OUT_DIR is writable");
}
