//! With the `tinybvh` feature: compiles `ffi/tinybvh_shim.cpp`, quiver-lab's C entry points
//! into tinybvh's CPU layouts, against the `tiny_bvh.h` that tinybvh-rs ships and compiles.
//! Without it, nothing.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    #[cfg(feature = "tinybvh")]
    tinybvh::compile();
}

#[cfg(feature = "tinybvh")]
mod tinybvh {
    use std::path::PathBuf;
    use std::process::Command;

    /// The tinybvh-rs version whose header the shim is written against (and whose build
    /// flags, `-std=c++20 -march=native`, it repeats: the classes' layout depends on them).
    const CRATE: &str = "tinybvh-rs";

    pub fn compile() {
        println!("cargo:rerun-if-changed=ffi/tinybvh_shim.cpp");
        let header_dir = header_dir();
        cc::Build::new()
            .cpp(true)
            .file("ffi/tinybvh_shim.cpp")
            .include(&header_dir)
            .std("c++20")
            .flag("-march=native")
            // tiny_bvh.h warns about what it does not use; the shim's own code is small.
            .warnings(false)
            .compile("quiver_tinybvh_shim");
    }

    /// Where tinybvh-rs's `tiny_bvh.h` is: cargo knows where it unpacked the crate, so ask it
    /// (`cargo metadata`, offline: the crate is already there, being built beside us).
    fn header_dir() -> PathBuf {
        if let Ok(dir) = std::env::var("QUIVER_TINYBVH_HEADER_DIR") {
            return PathBuf::from(dir);
        }
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let manifest =
            PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("Cargo.toml");
        // Only this target's packages: the others (Windows crates) may never have been fetched.
        let target = std::env::var("TARGET").unwrap();
        // Offline first (the crate is already there); on a fresh machine cargo may not yet
        // have fetched every package the metadata names (other targets' dev-dependencies),
        // and then it may fetch them.
        let metadata = |offline: bool| {
            let mut c = Command::new(&cargo);
            c.args(["metadata", "--format-version", "1"]);
            if offline {
                c.arg("--offline");
            }
            c.args(["--features", "quiver-lab/tinybvh", "--filter-platform"])
                .arg(&target)
                .arg("--manifest-path")
                .arg(&manifest)
                .output()
                .expect("running cargo metadata to find tinybvh-rs")
        };
        let mut out = metadata(true);
        if !out.status.success() {
            out = metadata(false);
        }
        assert!(
            out.status.success(),
            "cargo metadata failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let meta: serde_json::Value =
            serde_json::from_slice(&out.stdout).expect("cargo metadata's JSON");
        let manifest_path = meta["packages"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|p| p["name"] == CRATE)
            .and_then(|p| p["manifest_path"].as_str())
            .expect("tinybvh-rs among the packages (the feature depends on it)");
        let dir = PathBuf::from(manifest_path)
            .parent()
            .expect("a manifest's directory")
            .join("ffi/tinybvh");
        assert!(
            dir.join("tiny_bvh.h").is_file(),
            "no tiny_bvh.h in {}",
            dir.display()
        );
        println!(
            "cargo:rerun-if-changed={}",
            dir.join("tiny_bvh.h").display()
        );
        dir
    }
}
