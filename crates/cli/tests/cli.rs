//! The `quiver` binary as a user runs it: bad input gives exit code 2 and one `error:` line
//! naming the flag, file or value, never a panic (exit code 101); output paths and numbers are
//! checked before any work; files appear whole or not at all. Scenes and ray counts are tiny
//! so the whole file runs in seconds.

use assert_cmd::prelude::*;
use assert_cmd::Command;
use predicates::prelude::*;
use std::path::Path;

/// The `quiver` binary cargo built for these tests.
const QUIVER: &str = env!("CARGO_BIN_EXE_quiver");

fn quiver() -> Command {
    Command::new(QUIVER)
}

/// `quiver` with `line`'s words as arguments (no word in these tests has a space).
fn run(line: &str) -> Command {
    let mut c = quiver();
    c.args(line.split(' '));
    c
}

/// The names in `dir`, sorted (hidden temporary files included).
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Every subcommand's smallest run on `scene`; `dir` takes the files they write.
fn every_command(scene: &str, dir: &Path) -> Vec<Vec<String>> {
    let png = dir.join("r.png").display().to_string();
    let tiny = ["--rays", "10", "--reps", "1", "--threads", "1"];
    let with = |head: &[&str], tail: &[&str]| -> Vec<String> {
        head.iter().chain(tail).map(|s| s.to_string()).collect()
    };
    vec![
        with(&["build", scene], &[]),
        with(&["render", scene, "--res", "8", "-o", &png], &[]),
        with(
            &["layouts", scene, "--layout", "bvh2-dfs", "--res", "8"],
            &tiny,
        ),
        with(&["accuracy", scene, "--sphere", "0"], &tiny),
        with(&["bench", scene, "--res", "8"], &tiny),
        with(&["packets", scene, "--res", "8"], &tiny),
        with(
            &["predict", scene, "--lines", "10", "--res", "8", "--time"],
            &tiny,
        ),
        with(
            &[
                "render", scene, "--res", "8", "--havran", "--reps", "1", "-o", &png,
            ],
            &[],
        ),
        with(
            &["builders", scene, "--res", "8", "--build-reps", "1"],
            &tiny,
        ),
    ]
}

// Defect 1: empty scenes.

#[test]
fn empty_generated_scene_works_in_every_command() {
    let dir = tempfile::tempdir().unwrap();
    for args in every_command("soup0", dir.path()) {
        quiver()
            .args(&args)
            .current_dir(dir.path())
            .assert()
            .success()
            // packets used to print `NaNx` for the empty shadow-ray set.
            .stdout(predicate::str::contains("NaN").not())
            .stderr(predicate::str::contains("panicked").not());
    }
    run("gen soup0").assert().success();
}

#[test]
fn bench_on_empty_scene_does_not_panic() {
    run("bench soup0 --rays 10 --reps 1 --threads 1")
        .assert()
        .success()
        .stdout(predicate::str::contains("soup0"));
}

#[test]
fn empty_obj_file_works_or_names_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("empty.obj");
    std::fs::write(&obj, "# no faces\n").unwrap();
    let obj = obj.display().to_string();
    for args in every_command(&obj, dir.path()) {
        quiver()
            .args(&args)
            .assert()
            .success()
            .stdout(predicate::str::contains("NaN").not())
            .stderr(predicate::str::contains("panicked").not());
    }
    // gen either writes an NFF that reads back, or says why it cannot: the OBJ loader puts
    // the light of a scene without faces at -inf (empty bounds), which NFF cannot carry.
    let nff = dir.path().join("empty.nff");
    let out = run("gen -o").arg(&nff).arg(&obj).output().unwrap();
    if out.status.success() {
        quiver().arg("build").arg(&nff).assert().success();
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(
            err.starts_with("error: ") && err.contains("empty.obj"),
            "{err}"
        );
        assert!(!nff.exists());
    }
}

// Defect 2: thread counts.

#[test]
fn zero_threads_is_refused_everywhere() {
    let commands = [
        "build tetra1",
        "render tetra1 --res 8",
        "layouts tetra1 --rays 10 --res 8 --reps 1",
        "accuracy tetra1 --rays 10 --reps 1 --sphere 0",
        "bench tetra1 --rays 10 --reps 1",
        "packets tetra1 --rays 10 --reps 1 --res 8",
        "predict tetra1 --lines 10 --rays 10 --reps 1 --res 8 --time",
        "costs tetra1 --res 8 --reps 1",
    ];
    let dir = tempfile::tempdir().unwrap();
    for line in commands {
        run(line)
            .args(["--threads", "0"])
            .current_dir(dir.path())
            .assert()
            .code(2)
            .stdout("")
            .stderr(
                predicate::str::contains("'--threads <THREADS>'")
                    .and(predicate::str::contains("'0'")),
            );
    }
    // layouts takes a list: a 0 anywhere in it is refused too.
    run("layouts tetra1 --threads 1,0")
        .assert()
        .code(2)
        .stderr(predicate::str::contains("--threads"));
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
}

#[test]
fn bench_and_packets_measure_the_thread_counts_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    for line in [
        "bench tetra1 --rays 10 --reps 1 --res 8 --threads 1",
        "packets tetra1 --rays 10 --reps 1 --res 8 --threads 1",
    ] {
        let json = dir.path().join("report.json");
        run(line).arg("--json").arg(&json).assert().success();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let rows = report["rows"].as_array().unwrap();
        assert!(!rows.is_empty());
        assert!(rows.iter().all(|r| r["threads"] == 1), "{line}: {rows:?}");
        if line.starts_with("bench") {
            // tetra1's 4 triangles: one 256-byte 8-wide node, and at least the triangles'
            // own 36 bytes each beside it.
            // Every ray kind of the single-ray rounds, eye rays from the camera asked for.
            for kind in ["eye", "shadow", "diffuse", "incoherent"] {
                assert!(rows.iter().any(|r| r["rays"] == kind), "{kind}: {rows:?}");
            }
            assert_eq!(report["machine"]["eye_res"], 8);
            let memory = report["memory"].as_array().unwrap();
            let bvh8 = memory.iter().find(|m| m["kernel"] == "bvh8-dfs").unwrap();
            assert_eq!(bvh8["node_bytes"], 256, "{bvh8}");
            assert_eq!(bvh8["node_bytes_per_tri"], 64.0, "{bvh8}");
            assert!(bvh8["bytes"].as_u64().unwrap() >= 256 + 4 * 36, "{bvh8}");
            // It keeps what the walk reads (nodes, SIMD groups) and the four input indices
            // in leaf order a refit reads, no second copy of the triangles.
            assert_eq!(
                bvh8["kept_bytes"].as_u64().unwrap(),
                bvh8["bytes"].as_u64().unwrap() + 4 * 4,
                "{bvh8}"
            );
        }
        if line.starts_with("packets") {
            // Patch mode adds the first-bounce mirror rays of every eye hit.
            let mirror = rows.iter().find(|r| r["rays"] == "mirror");
            assert!(
                mirror.is_some_and(|r| r["count"].as_u64() > Some(0)),
                "{rows:?}"
            );
            // Diffuse bounce rays: one per eye hit, as the mirror rays.
            let diffuse = rows.iter().find(|r| r["rays"] == "diffuse");
            assert_eq!(
                diffuse.map(|r| &r["count"]),
                mirror.map(|r| &r["count"]),
                "{rows:?}"
            );
            assert_eq!(report["eye_res"], 8);
        }
    }
}

// Defect 3: output paths checked first; stdout errors.

#[test]
fn render_to_a_missing_directory_fails_before_rendering() {
    run("render tetra1 --res 8 -o /nonexistent/x.png")
        .assert()
        .code(2)
        .stdout("")
        .stderr(
            predicate::str::contains("--output /nonexistent/x.png")
                .and(predicate::str::contains("does not exist")),
        );
}

#[test]
fn bad_json_path_fails_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("x.png");
    // A directory as --json: no table on stdout, no PNG.
    run("render tetra1 --res 8 -o")
        .arg(&png)
        .arg("--json")
        .arg(dir.path())
        .assert()
        .code(2)
        .stdout("")
        .stderr(predicate::str::contains("--json").and(predicate::str::contains("is a directory")));
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
    run("build tetra1 --json")
        .arg(dir.path())
        .assert()
        .code(2)
        .stdout("");
    // A file where the directory should be.
    let file = dir.path().join("f");
    std::fs::write(&file, "").unwrap();
    run("build tetra1 --json")
        .arg(file.join("r.json"))
        .assert()
        .code(2)
        .stdout("")
        .stderr(predicate::str::contains("is not a directory"));
}

#[test]
fn every_output_flag_is_checked_before_work() {
    // Default sizes: a check that came after the work would show as a table on stdout and a
    // `cannot write` error instead of one naming the flag.
    let cases = [
        "gen tetra1 -o /nonexistent/s.nff",
        "render tetra1 --res 8 --heatmap /nonexistent/h.png",
        "layouts tetra1 --json /nonexistent/l.json",
        "accuracy tetra1 --plot /nonexistent/a.svg",
        "accuracy tetra1 --json /nonexistent/a.json",
        "bench tetra1 --json /nonexistent/b.json",
        "packets tetra1 --json /nonexistent/p.json",
        "predict tetra1 --json /nonexistent/p.json",
        "predict tetra1 --plot /nonexistent/p.svg",
        "costs tetra1 --json /nonexistent/c.json",
        "render tetra1 --res 8 --havran --json /nonexistent/h.json",
        "builders tetra1 --json /nonexistent/b.json",
        "builders tetra1 --plot /nonexistent/b.svg",
        "render tetra1 -o same.png --heatmap same.png",
    ];
    let dir = tempfile::tempdir().unwrap();
    for line in cases {
        run(line)
            .current_dir(dir.path())
            .assert()
            .code(2)
            .stdout("")
            .stderr(predicate::str::starts_with("error: --"));
    }
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
}

#[test]
fn accuracy_writes_a_plot_only_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        run("accuracy tetra1 --rays 10 --reps 1 --sphere 0")
            .args(["--threads", "1"])
            .args(extra)
            .current_dir(dir.path())
            .assert()
            .success();
    };
    run(&[]);
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
    run(&["--plot", "plot.svg"]);
    assert_eq!(names(dir.path()), ["plot.svg"]);
    let svg = std::fs::read_to_string(dir.path().join("plot.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.ends_with("</svg>\n"));
}

#[cfg(target_os = "linux")]
#[test]
fn full_stdout_is_an_error() {
    for args in [&["build", "tetra1"][..], &["gen", "tetra1"], &["--help"]] {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        // assert_cmd's own Command captures stdout; std's keeps the one given.
        std::process::Command::new(QUIVER)
            .args(args)
            .stdout(full)
            .assert()
            .code(2)
            .stderr(predicate::str::contains("cannot write to stdout"));
    }
}

/// A reader that stops early (`quiver ... | head`) is not an error: exit 0, nothing on stderr.
#[cfg(unix)]
#[test]
fn closed_pipe_exits_quietly() {
    for args in [&["build", "tetra1"][..], &["gen", "tetra4"]] {
        let mut child = std::process::Command::new(QUIVER)
            .args(args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Closing the read end at once: the child's first write meets a closed pipe.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{args:?}");
        assert_eq!(String::from_utf8_lossy(&out.stderr), "", "{args:?}");
    }
}

// Defect 4: whole files or none.

#[test]
fn written_files_are_complete_and_no_temp_file_remains() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run("render tetra1 --res 8 -o img.png --heatmap heat.png")
        .args(["--json", "render.json", "--threads", "1"])
        .current_dir(d)
        .assert()
        .success();
    run("gen tetra1 -o scene.nff")
        .current_dir(d)
        .assert()
        .success();
    run("build tetra1 --json build.json")
        .current_dir(d)
        .assert()
        .success();
    let want = "build.json heat.png img.png render.json scene.nff";
    assert_eq!(names(d).join(" "), want);
    for (png, side) in [("img.png", 8), ("heat.png", 9)] {
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(d.join(png)).unwrap(),
        ));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (side, side), "{png}");
    }
    for json in ["render.json", "build.json"] {
        let text = std::fs::read_to_string(d.join(json)).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["scene"], "tetra1", "{json}");
    }
    // The NFF reads back as the same scene.
    run("build scene.nff")
        .current_dir(d)
        .assert()
        .success()
        .stdout(predicate::str::is_match(r"primitives +4\n").unwrap());
}

#[test]
fn failed_run_leaves_previous_files_intact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("img.png"), "previous image").unwrap();
    std::fs::write(d.join("r.json"), "previous report").unwrap();
    // The report cannot be written: the image must not have been replaced either.
    run("render tetra1 --res 8 -o img.png --json no/r.json")
        .current_dir(d)
        .assert()
        .code(2);
    assert_eq!(
        std::fs::read_to_string(d.join("img.png")).unwrap(),
        "previous image"
    );
    assert_eq!(names(d), ["img.png", "r.json"]);
}

/// A write past the file-size limit (`ulimit -f`, what a full quota looks like) is an error
/// naming the file, not a death by SIGXFSZ: exit code 2, the previous file as it was, not a
/// truncated one, and no temporary left.
#[cfg(unix)]
#[test]
fn interrupted_write_leaves_previous_file_intact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("img.png"), "previous image").unwrap();
    // `ulimit -f 1`: at most one block (512 or 1024 bytes by shell) per file; a 64 x 64
    // render's PNG is larger, so the write fails part way.
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -f 1 && exec '{QUIVER}' render tetra3 --res 64 --threads 1 -o img.png"
        ))
        .current_dir(d)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cannot write img.png") && err.contains("too large"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(d.join("img.png")).unwrap(),
        "previous image"
    );
    assert_eq!(names(d), ["img.png"]);
}

// Defect 5: nonsense numbers; bench's default scenes.

#[test]
fn zero_and_nonsense_numbers_are_refused_naming_the_flag() {
    // Each command line is split at spaces; the flag is what the error must name.
    let cases = [
        ("packets tetra1 --rays 0 --reps 1 --res 8", "--rays"),
        ("packets tetra1 --rays 10 --reps 0 --res 8", "--reps"),
        ("packets tetra1 --rays 10 --reps 1 --res 0", "--res"),
        ("bench tetra1 --rays 0 --reps 1", "--rays"),
        ("bench tetra1 --rays 10 --reps 0", "--reps"),
        ("layouts tetra1 --rays 0 --res 8 --reps 1", "--rays"),
        ("layouts tetra1 --rays 10 --res 0 --reps 1", "--res"),
        ("layouts tetra1 --rays 10 --res 8 --reps 0", "--reps"),
        ("accuracy tetra1 --rays 0 --reps 1 --sphere 0", "--rays"),
        ("accuracy tetra1 --rays 10 --reps 0 --sphere 0", "--reps"),
        ("accuracy tetra1 --rays -5", "--rays"),
        ("render tetra1 --res 0", "--res"),
        ("render tetra1 --res 8 --havran --reps 0", "--reps"),
        ("predict tetra1 --lines 0", "--lines"),
        ("costs tetra1 --reps 0", "--reps"),
        ("build tetra1 --cost-model best", "--cost-model"),
        ("predict tetra1 --time --reps 0", "--reps"),
        ("render tetra1 --threads -2", "--threads"),
        ("gen tetra1 --patches --resolution 0", "--resolution"),
        ("build tetra1 --bins 1", "--bins"),
        ("build tetra1 --max-leaf 0", "--max-leaf"),
        ("build tetra1 --traversal-cost NaN", "--traversal-cost"),
        ("build tetra1 --intersection-cost -1", "--intersection-cost"),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (args, flag) in cases {
        run(args)
            .current_dir(dir.path())
            .assert()
            .code(2)
            .stdout("")
            .stderr(predicate::str::contains(flag));
    }
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
}

#[test]
fn bad_scene_names_and_files_are_named() {
    run("build nosuchscene7")
        .assert()
        .code(2)
        .stderr(predicate::str::contains("nosuchscene7"));
    run("build /nonexistent/mesh.obj")
        .assert()
        .code(2)
        .stderr(predicate::str::contains("/nonexistent/mesh.obj"));
    // A bad name after a good one fails before the good one is measured.
    run("bench tetra1 nosuchscene7 --rays 10 --reps 1")
        .assert()
        .code(2)
        .stdout("")
        .stderr(predicate::str::contains("nosuchscene7"));
}

/// `bench` used to default to a bunny path fixed when the binary was compiled, which breaks
/// once the binary is installed elsewhere or the source tree moves.
#[test]
fn bench_defaults_need_no_file_from_the_source_tree() {
    let binary = std::fs::read(QUIVER).unwrap();
    let baked = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data");
    assert!(
        !binary.windows(baked.len()).any(|w| w == baked.as_bytes()),
        "the binary refers to {baked}"
    );
    run("bench --help")
        .assert()
        .success()
        .stdout(predicate::str::contains("teapot12").and(predicate::str::contains("bunny.obj")));
}

#[test]
fn non_finite_input_is_refused_unless_dropping_is_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("nan.nff");
    std::fs::write(
        &file,
        "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 8 8\n\
         f 1 1 1 1 0 0 0 1\ns 0 0 0 1\ns nan 0 0 1\n",
    )
    .unwrap();
    let path = file.to_str().unwrap();
    quiver()
        .args(["build", path])
        .assert()
        .code(2)
        .stderr(predicate::str::contains("nan.nff:10").and(predicate::str::contains("NaN")));
    quiver()
        .args(["build", path, "--drop-non-finite"])
        .assert()
        .success()
        .stderr(predicate::str::contains("warning").and(predicate::str::contains("dropped 1")));
}

#[test]
fn a_camera_looking_along_its_up_vector_is_refused_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("up.nff");
    std::fs::write(
        &file,
        "v\nfrom 0 0 5\nat 0 0 0\nup 0 0 1\nangle 45\nhither 1\nresolution 8 8\n\
         f 1 1 1 1 0 0 0 1\ns 0 0 0 1\n",
    )
    .unwrap();
    let png = dir.path().join("out.png");
    quiver()
        .args(["render", file.to_str().unwrap(), "--res", "8", "-o"])
        .arg(&png)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("up.nff:4").and(predicate::str::contains("'up'")));
    assert!(!png.exists(), "no image for a refused camera");
}

#[test]
fn an_unknown_quiver_isa_is_an_error_before_any_work() {
    // A misspelt value used to be ignored and the run measured on the AVX2 kernels.
    for value in ["Portable", "sse", "avx512f"] {
        run("build tetra1")
            .env("QUIVER_ISA", value)
            .assert()
            .code(2)
            .stdout(predicate::str::is_empty())
            .stderr(predicate::str::contains(format!("'{value}'")))
            .stderr(predicate::str::contains("portable, avx2, avx512"));
    }
    // Every name is accepted, also where the CPU lacks it (the best below it runs).
    for value in ["portable", "avx2", "avx512", ""] {
        run("build tetra1")
            .env("QUIVER_ISA", value)
            .assert()
            .success();
    }
}

// Issue 29: outputs never replace what they should not; interrupted writes leave nothing.

/// A file's bytes, or a description of what is there instead, to compare before and after.
fn snapshot(path: &Path) -> String {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    match std::fs::symlink_metadata(path) {
        Err(_) => "absent".into(),
        Ok(m) if m.file_type().is_symlink() => {
            format!("link to {}", std::fs::read_link(path).unwrap().display())
        }
        Ok(m) if m.is_file() => format!(
            "file ino {} mode {:o}: {:?}",
            m.ino(),
            m.mode(),
            std::fs::read(path).unwrap()
        ),
        Ok(m) if m.is_dir() => format!("directory {:?}", names(path)),
        Ok(m) if m.file_type().is_fifo() => format!("fifo ino {}", m.ino()),
        Ok(m) if m.file_type().is_char_device() => format!("char device {:x}", m.rdev()),
        Ok(m) => format!("other {:o}", m.mode()),
    }
}

/// Makes a FIFO at `path`.
fn mkfifo(path: &Path) {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: `c` is a valid NUL-terminated path for the duration of the call.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0, "mkfifo");
}

/// A character device like /dev/null at `path`, if this process may make one (root).
fn mknod_null(path: &Path) -> bool {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: `c` is a valid NUL-terminated path; makedev builds the number of /dev/null.
    unsafe { libc::mknod(c.as_ptr(), libc::S_IFCHR | 0o644, libc::makedev(1, 3)) == 0 }
}

/// A small OBJ scene to use as a command's input file.
const TRIANGLE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

#[test]
fn an_output_that_is_the_input_is_refused_before_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("victim.obj"), TRIANGLE_OBJ).unwrap();
    gen_nff(d, "tetra1", "victim.nff");
    std::fs::hard_link(d.join("victim.obj"), d.join("hard.obj")).unwrap();
    std::os::unix::fs::symlink("victim.obj", d.join("soft.obj")).unwrap();
    let before: Vec<String> = names(d).iter().map(|n| snapshot(&d.join(n))).collect();
    let cases = [
        (
            "render victim.obj --res 8 -o victim.obj",
            "--output victim.obj",
        ),
        (
            "render victim.obj --res 8 --heatmap hard.obj",
            "--heatmap hard.obj",
        ),
        (
            "render victim.obj --res 8 --json soft.obj",
            "--json soft.obj",
        ),
        ("build victim.obj --json victim.obj", "--json victim.obj"),
        ("build soft.obj --json hard.obj", "--json hard.obj"),
        ("gen victim.nff -o victim.nff", "--output victim.nff"),
        (
            "layouts tetra1 victim.obj --json victim.obj",
            "--json victim.obj",
        ),
    ];
    for (line, named) in cases {
        run(line).current_dir(d).assert().code(2).stdout("").stderr(
            predicate::str::starts_with(format!("error: {named}: "))
                .and(predicate::str::contains("is the scene file")),
        );
    }
    let after: Vec<String> = names(d).iter().map(|n| snapshot(&d.join(n))).collect();
    assert_eq!(
        before, after,
        "the inputs and links are untouched, nothing added"
    );
}

/// Writes `scene` as NFF to `dir/name` with `quiver gen`.
fn gen_nff(dir: &Path, scene: &str, name: &str) {
    run("gen")
        .arg(scene)
        .arg("-o")
        .arg(name)
        .current_dir(dir)
        .assert()
        .success();
}

#[test]
fn devices_and_descriptors_are_written_in_place_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::os::unix::fs::symlink("/dev/null", d.join("null-link")).unwrap();
    std::os::unix::fs::symlink("/proc/self/fd/1", d.join("stdout-link")).unwrap();
    let made_device = mknod_null(&d.join("fakenull"));
    let mut outputs = vec!["null-link", "/dev/null"];
    if made_device {
        outputs.push("fakenull");
    }
    let before: Vec<String> = names(d).iter().map(|n| snapshot(&d.join(n))).collect();
    for out in &outputs {
        run("gen tetra2 -o")
            .arg(out)
            .current_dir(d)
            .assert()
            .success()
            .stdout("");
        run("render tetra1 --res 8 --threads 1 -o")
            .arg(out)
            .args(["--heatmap", out, "--json", out])
            .current_dir(d)
            .assert()
            .success();
    }
    // Through a link to this process's stdout, and /dev/stdout itself: the scene arrives on
    // stdout, and the link is still the link.
    let nff = run("gen tetra1").output().unwrap().stdout;
    for out in ["stdout-link", "/dev/stdout"] {
        run("gen tetra1 -o")
            .arg(out)
            .current_dir(d)
            .assert()
            .success()
            .stdout(nff.clone());
    }
    let after: Vec<String> = names(d).iter().map(|n| snapshot(&d.join(n))).collect();
    assert_eq!(
        before, after,
        "devices are still devices, links still links"
    );
    if made_device {
        assert!(before.iter().any(|s| s == "char device 103"), "{before:?}");
    }
}

#[test]
fn directories_fifos_and_dangling_directories_are_refused_before_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("sub")).unwrap();
    mkfifo(&d.join("fifo"));
    std::os::unix::fs::symlink("fifo", d.join("fifo-link")).unwrap();
    std::os::unix::fs::symlink("sub", d.join("dir-link")).unwrap();
    std::os::unix::fs::symlink("nowhere/x.png", d.join("dangling")).unwrap();
    std::os::unix::fs::symlink("loop-b", d.join("loop-a")).unwrap();
    std::os::unix::fs::symlink("loop-a", d.join("loop-b")).unwrap();
    let before: Vec<String> = names(d).iter().map(|n| snapshot(&d.join(n))).collect();
    let cases = [
        ("nodir/", "names a directory"),
        ("sub/", "names a directory"),
        ("sub/.", "names a directory"),
        ("sub", "is a directory"),
        ("dir-link", "is a symbolic link to sub, a directory"),
        ("fifo", "is a FIFO"),
        ("fifo-link", "is a symbolic link to fifo, a FIFO"),
        ("dangling", "directory nowhere does not exist"),
        ("loop-a", "levels of symbolic links"),
    ];
    for (out, why) in cases {
        // render's default scene: a check after the work would take seconds and print a table.
        for flag in ["-o", "--heatmap", "--json"] {
            let named = if flag == "-o" { "--output" } else { flag };
            run("render --res 64")
                .args([flag, out])
                .current_dir(d)
                .assert()
                .code(2)
                .stdout("")
                .stderr(
                    predicate::str::starts_with(format!("error: {named} {out}: "))
                        .and(predicate::str::contains(why)),
                );
        }
    }
    let after: Vec<String> = names(d).iter().map(|n| snapshot(&d.join(n))).collect();
    assert_eq!(before, after);
}

#[test]
fn a_symbolic_link_is_followed_and_kept_and_permissions_survive() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("data")).unwrap();
    std::fs::write(d.join("data/report.json"), "old").unwrap();
    std::fs::set_permissions(
        d.join("data/report.json"),
        std::fs::Permissions::from_mode(0o640),
    )
    .unwrap();
    std::os::unix::fs::symlink("data/report.json", d.join("report.json")).unwrap();
    // A dangling link into an existing directory: the file is created where it points.
    std::os::unix::fs::symlink("data/new.nff", d.join("new.nff")).unwrap();
    run("build tetra1 --json report.json")
        .current_dir(d)
        .assert()
        .success();
    run("gen tetra1 -o new.nff")
        .current_dir(d)
        .assert()
        .success();
    assert_eq!(snapshot(&d.join("report.json")), "link to data/report.json");
    assert_eq!(snapshot(&d.join("new.nff")), "link to data/new.nff");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("data/report.json")).unwrap())
            .unwrap();
    assert_eq!(report["scene"], "tetra1");
    let mode = std::fs::metadata(d.join("data/report.json"))
        .unwrap()
        .permissions()
        .mode();
    assert_eq!(mode & 0o777, 0o640);
    assert_eq!(
        std::fs::read(d.join("data/new.nff")).unwrap(),
        run("gen tetra1").output().unwrap().stdout
    );
    assert_eq!(names(&d.join("data")), ["new.nff", "report.json"]);
}

/// SIGINT or SIGTERM in the middle of a write: the process dies of the signal, the previous
/// file is untouched and no temporary remains. The temporary exists only while the file is
/// written, so the signal is sent as soon as it appears; a run that finished first is
/// retried, and at least one of the attempts must have been caught mid-write.
#[test]
fn a_signal_during_a_write_leaves_neither_temporary_nor_truncated_file() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = run("gen tetra9").output().unwrap().stdout;
    for signal in [libc::SIGINT, libc::SIGTERM] {
        let mut caught = 0;
        for _ in 0..20 {
            std::fs::write(d.join("big.nff"), "previous").unwrap();
            let mut child = std::process::Command::new(QUIVER)
                .args(["gen", "tetra9", "-o", "big.nff"])
                .current_dir(d)
                .spawn()
                .unwrap();
            let pid = child.id() as i32;
            let mut sent = false;
            while child.try_wait().unwrap().is_none() {
                if names(d).iter().any(|n| n.ends_with(".tmp")) {
                    // SAFETY: `pid` is our child's, not yet reaped, so it names that process.
                    unsafe { libc::kill(pid, signal) };
                    sent = true;
                    break;
                }
                std::thread::sleep(std::time::Duration::from_micros(200));
            }
            let status = child.wait().unwrap();
            // Whatever the moment: the previous file, or the new one whole (a signal after
            // the rename), never a truncated one.
            let now = std::fs::read(d.join("big.nff")).unwrap();
            assert!(now == b"previous" || now == whole, "{} bytes", now.len());
            if sent && status.signal() == Some(signal) {
                caught += usize::from(now == b"previous");
            } else {
                assert!(status.success(), "{status:?}");
                assert!(now == whole);
            }
            assert_eq!(names(d), ["big.nff"], "no temporary after signal {signal}");
            if caught >= 2 {
                break;
            }
        }
        assert!(caught > 0, "signal {signal} never arrived mid-write");
    }
}

/// A SIGKILL cannot be caught: its temporary stays, named so the next run writing the same
/// file recognises and removes it. A temporary of a live process (another run writing the
/// same file now) and every other file are left alone.
#[test]
fn the_next_run_sweeps_a_killed_runs_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut child = std::process::Command::new(QUIVER)
        // A fixed limit: while other tests hold memory, what the system has available can
        // drop below what gen estimates, and a refused run writes no temporary to kill.
        .args(["gen", "tetra10", "-o", "big.nff", "--max-memory", "8G"])
        .current_dir(d)
        .spawn()
        .unwrap();
    while child.try_wait().unwrap().is_none() && !names(d).iter().any(|n| n.ends_with(".tmp")) {
        std::thread::sleep(std::time::Duration::from_micros(200));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let stale = names(d);
    assert!(stale.iter().any(|n| n.ends_with(".tmp")), "{stale:?}");
    let live = format!(".big.nff.quiver-{}-0.tmp", std::process::id());
    std::fs::write(d.join(&live), "a live run's").unwrap();
    std::fs::write(d.join(".big.nff.other.tmp"), "not ours").unwrap();
    std::fs::write(
        d.join(".small.nff.quiver-999999999-0.tmp"),
        "another file's",
    )
    .unwrap();
    run("gen tetra1 -o big.nff")
        .current_dir(d)
        .assert()
        .success();
    let mut want = vec![
        ".big.nff.other.tmp".to_string(),
        live,
        ".small.nff.quiver-999999999-0.tmp".to_string(),
        "big.nff".to_string(),
    ];
    want.sort();
    assert_eq!(names(d), want, "the killed run's {stale:?} is gone");
}

/// A small deterministic random number generator (SplitMix64) for the property test.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// What the property test puts at an output name before the run.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Entry {
    Absent,
    File,
    Directory,
    LinkToFile,
    LinkChainToFile,
    LinkToDirectory,
    DanglingLink,
    DanglingLinkNoDirectory,
    Fifo,
    LinkToFifo,
    LinkToDevNull,
    LinkToStdout,
    HardLinkToInput,
    LinkToInput,
    CharDevice,
    LinkLoop,
}

const ENTRIES: [Entry; 16] = [
    Entry::Absent,
    Entry::File,
    Entry::Directory,
    Entry::LinkToFile,
    Entry::LinkChainToFile,
    Entry::LinkToDirectory,
    Entry::DanglingLink,
    Entry::DanglingLinkNoDirectory,
    Entry::Fifo,
    Entry::LinkToFifo,
    Entry::LinkToDevNull,
    Entry::LinkToStdout,
    Entry::HardLinkToInput,
    Entry::LinkToInput,
    Entry::CharDevice,
    Entry::LinkLoop,
];

/// What the documented output rule says a path leads to (the test's own model of it).
#[derive(Clone, Debug, PartialEq)]
enum Expect {
    /// The file at this path (relative to the test directory) is replaced or created.
    Replace(String),
    /// Written in place: nothing in the directory changes.
    Direct,
    /// Refused before any work, with this in the message.
    Refuse(&'static str),
}

/// Creates `entry` at `dir/name` (helper files get names derived from `name`) and returns what
/// writing to `name` must do.
fn make_entry(dir: &Path, name: &str, entry: Entry, rng: &mut Rng, root: bool) -> Expect {
    use std::os::unix::fs::symlink;
    let p = dir.join(name);
    let bytes: Vec<u8> = (0..rng.below(64)).map(|_| rng.next() as u8).collect();
    match entry {
        Entry::Absent => {
            if rng.below(2) == 0 {
                // A killed run's temporary, to be swept when this name is written.
                std::fs::write(dir.join(format!(".{name}.quiver-2147483646-0.tmp")), "x").unwrap();
            }
            Expect::Replace(name.into())
        }
        Entry::File => {
            std::fs::write(&p, bytes).unwrap();
            Expect::Replace(name.into())
        }
        Entry::Directory => {
            std::fs::create_dir(&p).unwrap();
            std::fs::write(p.join("inside"), bytes).unwrap();
            Expect::Refuse("is a directory")
        }
        Entry::LinkToFile => {
            let t = format!("{name}-target");
            std::fs::write(dir.join(&t), bytes).unwrap();
            symlink(&t, &p).unwrap();
            Expect::Replace(t)
        }
        Entry::LinkChainToFile => {
            let (mid, t) = (format!("{name}-mid"), format!("{name}-target"));
            std::fs::write(dir.join(&t), bytes).unwrap();
            symlink(&t, dir.join(&mid)).unwrap();
            symlink(dir.join(&mid), &p).unwrap();
            Expect::Replace(t)
        }
        Entry::LinkToDirectory => {
            let t = format!("{name}-dir");
            std::fs::create_dir(dir.join(&t)).unwrap();
            symlink(&t, &p).unwrap();
            Expect::Refuse("a directory")
        }
        Entry::DanglingLink => {
            let t = format!("{name}-new");
            symlink(&t, &p).unwrap();
            Expect::Replace(t)
        }
        Entry::DanglingLinkNoDirectory => {
            symlink(format!("{name}-nodir/x"), &p).unwrap();
            Expect::Refuse("does not exist")
        }
        Entry::Fifo => {
            mkfifo(&p);
            Expect::Refuse("FIFO")
        }
        Entry::LinkToFifo => {
            let t = format!("{name}-fifo");
            mkfifo(&dir.join(&t));
            symlink(&t, &p).unwrap();
            Expect::Refuse("FIFO")
        }
        Entry::LinkToDevNull => {
            symlink("/dev/null", &p).unwrap();
            Expect::Direct
        }
        Entry::LinkToStdout => {
            symlink("/proc/self/fd/1", &p).unwrap();
            Expect::Direct
        }
        Entry::HardLinkToInput => {
            std::fs::hard_link(dir.join("in.nff"), &p).unwrap();
            Expect::Refuse("is the scene file")
        }
        Entry::LinkToInput => {
            symlink("in.nff", &p).unwrap();
            Expect::Refuse("is the scene file")
        }
        Entry::CharDevice if root => {
            assert!(mknod_null(&p));
            Expect::Direct
        }
        Entry::CharDevice => {
            symlink("/dev/zero", &p).unwrap();
            Expect::Direct
        }
        Entry::LinkLoop => {
            let other = format!("{name}-loop");
            symlink(&other, &p).unwrap();
            symlink(name, dir.join(&other)).unwrap();
            Expect::Refuse("levels of symbolic links")
        }
    }
}

/// Every path under `dir` (recursively, not following links) with [`snapshot`]'s description
/// (directories as "directory", their entries listed on their own).
fn tree(dir: &Path) -> std::collections::BTreeMap<String, String> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for name in names(&d) {
            let p = d.join(&name);
            let key = p.strip_prefix(dir).unwrap().display().to_string();
            let m = std::fs::symlink_metadata(&p).unwrap();
            if m.is_dir() {
                out.insert(key, "directory".into());
                stack.push(p);
            } else {
                out.insert(key, snapshot(&p));
            }
        }
    }
    out
}

/// One random case: a directory holding an input scene and entries of random kinds, one
/// command writing one to three outputs at spellings of those entries. Checks the outcome
/// against the model: refused (exit 2, the flag and path named, nothing changed) when any
/// output must be refused, else success with each replaced file whole and valid, devices and
/// links untouched, nothing else changed; the input never changes and no temporary remains.
fn output_case(rng: &mut Rng, root: bool, nff: &[u8]) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("in.nff"), nff).unwrap();
    let names_used = ["a", "b", "c"];
    let mut expect = Vec::new();
    for name in names_used {
        let entry = ENTRIES[rng.below(ENTRIES.len())];
        expect.push(make_entry(d, name, entry, rng, root));
    }
    // The command and its output flags.
    let (mut args, flags, kinds): (Vec<String>, Vec<&str>, Vec<&str>) = match rng.below(4) {
        0 => (vec!["gen".into(), "in.nff".into()], vec!["-o"], vec!["nff"]),
        1 => (
            vec!["build".into(), "in.nff".into()],
            vec!["--json"],
            vec!["json"],
        ),
        _ => {
            let mut flags = vec!["-o"];
            let mut kinds = vec!["png"];
            if rng.below(2) == 0 {
                flags.push("--heatmap");
                kinds.push("png");
            }
            if rng.below(2) == 0 {
                flags.push("--json");
                kinds.push("json");
            }
            let head = ["render", "in.nff", "--res", "4", "--threads", "1"];
            (head.map(String::from).to_vec(), flags, kinds)
        }
    };
    // Each output: an entry under one of its spellings, or a special path.
    let mut outcome: Vec<(String, Expect)> = Vec::new();
    for _ in &flags {
        let k = rng.below(names_used.len());
        let name = names_used[k];
        let abs = d.join(name).display().to_string();
        let (path, e) = match rng.below(10) {
            0 => (format!("{name}/"), Expect::Refuse("names a directory")),
            1 => ("in.nff".into(), Expect::Refuse("is the scene file")),
            2 => ("/dev/null".into(), Expect::Direct),
            3 => ("missing/x".into(), Expect::Refuse("does not exist")),
            4 => (format!("./{name}"), expect[k].clone()),
            5 => (abs, expect[k].clone()),
            _ => (name.to_string(), expect[k].clone()),
        };
        outcome.push((path, e));
    }
    // Two outputs replacing the same file: the second would silently replace the first.
    let mut refuse_dup = None;
    for i in 0..outcome.len() {
        for j in 0..i {
            if let (Expect::Replace(a), Expect::Replace(b)) = (&outcome[i].1, &outcome[j].1) {
                if a == b && refuse_dup.is_none() {
                    refuse_dup = Some(i);
                }
            }
        }
    }
    for (flag, (path, _)) in flags.iter().zip(&outcome) {
        args.push(flag.to_string());
        args.push(path.clone());
    }
    let before = tree(d);
    // QUIVER_BIN: a copy of the binary, so a long run is not fed a rebuilt one mid-way.
    let binary = std::env::var("QUIVER_BIN").unwrap_or_else(|_| QUIVER.into());
    let out = std::process::Command::new(binary)
        .args(&args)
        .current_dir(d)
        .output()
        .unwrap();
    let after = tree(d);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    let context = format!("{args:?}\nmodel {outcome:?}\nstderr {stderr}\nbefore {before:#?}");
    assert!(!stderr.contains("panicked"), "{context}");
    assert_eq!(after.get("in.nff"), before.get("in.nff"), "{context}");
    assert!(
        !after
            .keys()
            .any(|k| k.contains(".quiver-") && !before.contains_key(k)),
        "a temporary remained: {after:#?}\n{context}"
    );
    // The first refused output in flag order (a duplicate counts where it occurs).
    let refused = outcome
        .iter()
        .enumerate()
        .find_map(|(i, (path, e))| match e {
            Expect::Refuse(why) => Some((i, path.clone(), *why)),
            _ if refuse_dup == Some(i) => Some((i, path.clone(), "both name")),
            _ => None,
        });
    if let Some((i, path, why)) = refused {
        assert_eq!(out.status.code(), Some(2), "{context}");
        assert_eq!(stdout, "", "{context}");
        let flag = match flags[i] {
            "-o" => "--output",
            f => f,
        };
        let named = if why == "both name" {
            format!("and {flag} both name {path}")
        } else {
            format!("error: {flag} {path}: ")
        };
        assert!(
            stderr.contains(&named) && stderr.contains(why),
            "want {named} ... {why}\n{context}"
        );
        // Stale temporaries of earlier outputs may have been swept; nothing else changes.
        let keep = |m: &std::collections::BTreeMap<String, String>| {
            m.iter()
                .filter(|(k, _)| !k.contains(".quiver-2147483646-"))
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect::<Vec<_>>()
        };
        assert_eq!(keep(&before), keep(&after), "{context}");
        return;
    }
    assert!(out.status.success(), "{context}");
    let mut changed: Vec<(String, &str)> = Vec::new();
    for ((_, e), kind) in outcome.iter().zip(&kinds) {
        if let Expect::Replace(file) = e {
            changed.push((file.clone(), kind));
        }
    }
    for (key, value) in &after {
        if let Some((_, kind)) = changed.iter().find(|(f, _)| f == key) {
            assert!(value.starts_with("file "), "{key}: {value}\n{context}");
            let bytes = std::fs::read(d.join(key)).unwrap();
            let valid = match *kind {
                "png" => bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
                "json" => serde_json::from_slice::<serde_json::Value>(&bytes)
                    .is_ok_and(|v| v["scene"] == "in.nff"),
                _ => bytes.starts_with(b"# in.nff (written by quiver)\n"),
            };
            assert!(valid, "{key} is not a whole {kind}\n{context}");
        } else if key.contains(".quiver-2147483646-") {
            // A stale temporary survives only if its name was not written.
            let name = key
                .trim_start_matches('.')
                .split(".quiver-")
                .next()
                .unwrap();
            assert!(
                !changed.iter().any(|(f, _)| f == name),
                "stale {key} not swept\n{context}"
            );
        } else {
            assert_eq!(before.get(key), Some(value), "{key} changed\n{context}");
        }
    }
    for (file, _) in &changed {
        assert!(after.contains_key(file), "{file} not written\n{context}");
    }
    for key in before.keys() {
        assert!(
            after.contains_key(key) || key.contains(".quiver-2147483646-"),
            "{key} vanished\n{context}"
        );
    }
}

/// Property test of the output rule over random combinations of regular files, directories,
/// symbolic links (to files, directories, FIFOs, devices, stdout, the input, dangling, loops),
/// hard links, FIFOs, devices, `/dev/null` and the input itself, through `gen`, `build` and
/// `render` with one to three outputs. `QUIVER_OUTPUT_CASES` (default 40) cases, or as many as
/// fit in `QUIVER_OUTPUT_SECONDS`; `QUIVER_OUTPUT_SEED` picks the sequence, `QUIVER_BIN` the
/// binary. Prints the count.
#[test]
fn output_paths_property() {
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<u64>().ok());
    let seconds = env("QUIVER_OUTPUT_SECONDS");
    let cases = env("QUIVER_OUTPUT_CASES").unwrap_or(if seconds.is_some() { u64::MAX } else { 40 });
    let mut rng = Rng(env("QUIVER_OUTPUT_SEED").unwrap_or(29));
    let root = {
        let dir = tempfile::tempdir().unwrap();
        mknod_null(&dir.path().join("probe"))
    };
    let nff = run("gen tetra1").output().unwrap().stdout;
    let start = std::time::Instant::now();
    let mut runs = 0u64;
    while runs < cases && seconds.is_none_or(|s| start.elapsed().as_secs() < s) {
        output_case(&mut rng, root, &nff);
        runs += 1;
    }
    eprintln!(
        "output_paths_property: {runs} runs in {:?}",
        start.elapsed()
    );
}

/// Runs `quiver args` in `dir` and returns its exit code (None if a signal ended it), stdout,
/// stderr and peak resident memory in bytes, quiver's own.
///
/// A child's `ru_maxrss` starts at what its parent had resident when it forked (and exec keeps
/// the larger), so quiver is not spawned from this test process, which holds other tests'
/// data: a fresh run of this test binary doing only [`peak_launcher`] (a few MB) spawns it,
/// reaps it with `wait4` and reports.
fn run_measured(args: &[&str], dir: &Path) -> (Option<i32>, String, String, u64) {
    let report = tempfile::NamedTempFile::new().unwrap();
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "peak_launcher",
            "--exact",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
            "-q",
        ])
        .env("QUIVER_PEAK_ARGS", args.join("\u{1f}"))
        .env("QUIVER_PEAK_REPORT", report.path())
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "launcher: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.path()).unwrap()).unwrap();
    (
        r["code"].as_i64().map(|c| c as i32),
        r["stdout"].as_str().unwrap().to_string(),
        r["stderr"].as_str().unwrap().to_string(),
        r["peak"].as_u64().unwrap(),
    )
}

/// Not a test: [`run_measured`]'s launcher, run on its own in a fresh process (ignored in a
/// normal run). Spawns quiver with `QUIVER_PEAK_ARGS` (separated by U+001F) in the current
/// directory, reaps it with `wait4` for its resource usage, and writes its exit code, output
/// and peak resident memory to `QUIVER_PEAK_REPORT` as JSON.
#[test]
#[ignore = "run_measured's launcher, not a test"]
// `wait4` reaps the child itself, for its resource usage; std's `wait` would fail after it.
#[allow(clippy::zombie_processes)]
fn peak_launcher() {
    use std::io::Read;
    let (Ok(args), Ok(report)) = (
        std::env::var("QUIVER_PEAK_ARGS"),
        std::env::var("QUIVER_PEAK_REPORT"),
    ) else {
        panic!("QUIVER_PEAK_ARGS and QUIVER_PEAK_REPORT are run_measured's to set");
    };
    let mut child = std::process::Command::new(QUIVER)
        .args(args.split('\u{1f}'))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        out.read_to_string(&mut s).unwrap();
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        err.read_to_string(&mut s).unwrap();
        s
    });
    let mut status = 0;
    // SAFETY: all-zero is a valid `rusage`; `wait4` reaps exactly this child (std's `Child`
    // is never waited on afterwards) and writes only to the two locals.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let pid = unsafe { libc::wait4(child.id() as i32, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as i32);
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    let report_json = serde_json::json!({
        "code": code,
        "stdout": out.join().unwrap(),
        "stderr": err.join().unwrap(),
        "peak": usage.ru_maxrss as u64 * 1024,
    });
    std::fs::write(report, report_json.to_string()).unwrap();
}

/// Item 9: a scene path that is a device, a FIFO or a directory is refused without reading it
/// (a link to /dev/zero used to grow to 4 GB first), and so is a file over the 1 GiB limit,
/// from its size alone.
#[test]
fn special_and_oversized_scene_files_are_refused_without_reading() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.obj")).unwrap();
    std::os::unix::fs::symlink("/dev/urandom", d.join("random.nff")).unwrap();
    mkfifo(&d.join("pipe.obj"));
    std::fs::create_dir(d.join("dir.nff")).unwrap();
    // A sparse file one byte over the limit: no disk space, but its size says it all.
    let big = std::fs::File::create(d.join("big.obj")).unwrap();
    big.set_len((1 << 30) + 1).unwrap();
    let cases = [
        ("zero.obj", "is a character device, not a regular file"),
        ("random.nff", "is a character device, not a regular file"),
        ("pipe.obj", "is a FIFO (named pipe), not a regular file"),
        ("dir.nff", "is a directory, not a regular file"),
        (
            "big.obj",
            "1073741825 bytes, more than the 1073741824 a scene file may have",
        ),
    ];
    for (file, why) in cases {
        for command in ["build", "gen", "render"] {
            let (code, out, err, peak) = run_measured(&[command, file], d);
            assert_eq!(code, Some(2), "{command} {file}: {err}");
            assert_eq!(out, "");
            assert_eq!(err, format!("error: {file}: {why}\n"), "{command}");
            assert!(peak < 64 << 20, "{command} {file}: peak {peak} bytes");
        }
    }
    assert_eq!(
        names(d),
        ["big.obj", "dir.nff", "pipe.obj", "random.nff", "zero.obj"]
    );
}

/// Item 6: an OBJ (no camera of its own) far larger than 1.1e19 used to overflow the framing
/// camera's f32 arithmetic and render blank with exit 0 from a fixed view of the origin. Now
/// the framing camera sees it at any extent f32 can frame, and beyond that the load fails
/// naming the file and the reason.
#[test]
fn a_huge_obj_is_framed_or_refused_never_rendered_blank() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for scale in ["1", "2e19", "1e30", "3e37"] {
        let obj = format!(
            "v -{scale} -{scale} 0\nv {scale} -{scale} 0\nv 0 {scale} 0\nv 0 0 {scale}\nf 1 2 3\nf 1 2 4\nf 2 3 4\nf 3 1 4\n"
        );
        std::fs::write(d.join("big.obj"), obj).unwrap();
        run("render big.obj --res 16 --threads 1 -o big.png --json big.json")
            .current_dir(d)
            .assert()
            .success();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("big.json")).unwrap()).unwrap();
        let (eye, hit) = (&report["rays"]["eye"], &report["rays"]["eye_hit"]);
        // The tetrahedron fills a good part of the 45° view: neither blank nor all of it.
        let share = hit.as_f64().unwrap() / eye.as_f64().unwrap();
        assert!(
            (0.05..0.95).contains(&share),
            "scale {scale}: {hit} of {eye}"
        );
    }
    std::fs::write(
        d.join("huge.obj"),
        "v -2e38 -2e38 -2e38\nv 2e38 -2e38 0\nv 0 2e38 2e38\nf 1 2 3\n",
    )
    .unwrap();
    for line in ["render huge.obj --res 16 -o huge.png", "build huge.obj"] {
        run(line)
            .current_dir(d)
            .assert()
            .code(2)
            .stdout("")
            .stderr(predicate::str::starts_with(
                "error: huge.obj: mesh files bring no view, and no camera can frame these bounds",
            ));
    }
}

/// The estimate in bytes a refusal states (`needs about 2.8 GiB [3035641824 bytes]`).
fn estimate_in(err: &str) -> u64 {
    let start = err
        .find(" [")
        .unwrap_or_else(|| panic!("no estimate in {err}"))
        + 2;
    let end = start + err[start..].find(" bytes]").unwrap();
    err[start..end].parse().unwrap()
}

/// Items 7, 8 and point 2: sizes the CLI accepts but this machine could not hold are refused
/// before any work, naming the estimate, its parts and the limit: exit 2, nothing written,
/// and only the memory a refusal takes (the audit saw 7 GB and 23 GB before aborts).
#[test]
fn sizes_beyond_the_memory_limit_are_refused_before_work_with_the_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases = [
        (
            "build balls6 --patches",
            "build balls6 --patches: needs about ",
        ),
        (
            "build rings40 --patches",
            "build rings40 --patches: needs about ",
        ),
        (
            "build lattice60 --patches",
            "build lattice60 --patches: needs about ",
        ),
        ("build soup50000000", "build soup50000000: needs about "),
        (
            "render balls6 --patches --res 64",
            "render balls6 --res 64 --patches: ",
        ),
        (
            "render tetra2 --res 16384 --max-memory 1G",
            "render tetra2 --res 16384: needs about 2.8 GiB",
        ),
        (
            "render tetra2 --res 4096 --heatmap h.png --havran --max-memory 1G",
            "render tetra2 --res 4096: needs about",
        ),
        ("bench balls6", "bench balls6: needs about"),
        ("packets rings40", "packets rings40: needs about"),
        ("builders lattice60", "builders lattice60: needs about"),
        (
            "predict tetra4 --lines 100000000 --max-memory 4G",
            "predict tetra4: needs about",
        ),
        (
            "layouts tetra1 --rays 100000000 --max-memory 2G",
            "layouts tetra1: needs about",
        ),
        (
            "costs tetra1 --res 8192 --max-memory 2G",
            "costs tetra1: needs about",
        ),
        (
            "accuracy tetra1 --sphere 8 --max-memory 1G",
            "accuracy tetra1: needs about",
        ),
        (
            "gen soup50000000 --max-memory 1G",
            "gen soup50000000: needs about",
        ),
    ];
    for (line, want) in cases {
        let args: Vec<&str> = line.split(' ').collect();
        let (code, out, err, peak) = run_measured(&args, d);
        assert_eq!(code, Some(2), "{line}: {err}");
        assert_eq!(out, "", "{line}");
        assert!(err.starts_with(&format!("error: {want}")), "{line}: {err}");
        assert!(
            err.contains("more than the ") && err.contains("this run may use ("),
            "{err}"
        );
        // The estimate is more than the limit it is refused by.
        let limit = if line.contains("--max-memory") {
            let size = line.rsplit(' ').next().unwrap();
            size.trim_end_matches('G').parse::<u64>().unwrap() << 30
        } else {
            0
        };
        assert!(estimate_in(&err) > limit, "{err}");
        assert!(peak < 128 << 20, "{line}: {peak} bytes to refuse");
    }
    assert!(names(d).is_empty(), "{:?}", names(d));
}

/// The estimates are upper bounds: each command on a scene of some size, run for real, peaks
/// below the estimate it states when refused by `--max-memory 1`.
#[test]
fn memory_estimates_bound_what_runs_take() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("mesh.obj"), TRIANGLE_OBJ).unwrap();
    let cases = [
        "build soup200000 --threads 2",
        "build soup200000 --builder aac-fast --layout bvh4-dfs --threads 2",
        "build balls4 --patches --threads 2",
        "build balls5 --layout bvh4-quant --threads 2",
        "render teapot12 --res 1024 --threads 2 -o r.png --heatmap h.png --json r.json",
        "render tetra6 --res 128 --havran --reps 1 --threads 2 -o r.png",
        "render balls3 --patches --res 64 --threads 2 -o r.png",
        "gen balls4 --patches -o /dev/null",
        "layouts soup100000 --rays 100000 --res 64 --reps 1 --threads 1",
        "bench soup100000 --rays 10000 --res 64 --reps 1 --threads 1",
        "packets balls3 --res 64 --rays 10000 --reps 1 --threads 1",
        "predict soup50000 --lines 100000 --time --rays 10000 --res 64 --reps 1 --threads 1",
        "costs soup50000 --res 64 --reps 1 --threads 1",
        "builders soup20000 --res 32 --rays 1000 --build-reps 1 --reps 1 --threads 1",
        "accuracy soup50000 --rays 10000 --reps 1 --sphere 4 --threads 1",
        "build mesh.obj",
    ];
    for line in cases {
        let mut args: Vec<&str> = line.split(' ').collect();
        args.extend(["--max-memory", "1"]);
        let (code, _, err, _) = run_measured(&args, d);
        assert_eq!(code, Some(2), "{line}: {err}");
        let estimate = estimate_in(&err);
        args.truncate(args.len() - 2);
        let (code, _, err, peak) = run_measured(&args, d);
        assert_eq!(code, Some(0), "{line}: {err}");
        assert!(
            peak <= estimate,
            "{line}: peak {peak} bytes, estimate {estimate}"
        );
        // Not absurdly loose either: within 8 times the peak, or a few hundred MB.
        assert!(
            estimate <= (8 * peak).max(320 << 20),
            "{line}: peak {peak} bytes, estimate {estimate}"
        );
    }
    // Compressed and amplifying inputs (issue 49): a 1M-face `.ply.gz` of a few KB, a PLY of
    // one face of 2M corners, a glTF placing one 4,000-triangle mesh by 250 nodes. Each runs
    // whole without a limit; under half its peak it is refused (exit 2, naming the file)
    // without ever holding more than the limit. The files' sizes say nothing of what they
    // make: each reader checks the sizes it is about to allocate.
    amplifying_inputs(d);
    for (file, line) in [
        ("faces.ply.gz", "build faces.ply.gz --threads 1"),
        ("corners.ply", "build corners.ply --threads 1"),
        ("placed.gltf", "build placed.gltf --threads 1"),
    ] {
        let args: Vec<&str> = line.split(' ').collect();
        let (code, _, err, peak) = run_measured(&args, d);
        assert_eq!(code, Some(0), "{line}: {err}");
        let limit = peak / 2;
        let mut limited = args.clone();
        let limit_arg = limit.to_string();
        limited.extend(["--max-memory", &limit_arg]);
        let (code, _, err, refused_peak) = run_measured(&limited, d);
        assert_eq!(code, Some(2), "{line} at {limit}: {err}");
        assert!(err.contains(file), "{err}");
        assert!(
            refused_peak <= limit,
            "{line}: refused at a peak of {refused_peak} bytes, over the limit {limit}: {err}"
        );
    }
}

/// The files of the amplifying cases of `memory_estimates_bound_what_runs_take`, in `d`.
fn amplifying_inputs(d: &Path) {
    let head = |faces: usize, list: &str| {
        format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
             property float y\nproperty float z\nelement face {faces}\n\
             property list {list} vertex_indices\nend_header\n"
        )
        .into_bytes()
    };
    let tri: Vec<u8> = [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    // A million copies of one triangle, gzipped.
    let mut faces = head(1_000_000, "uchar uchar");
    faces.extend_from_slice(&tri);
    for _ in 0..1_000_000 {
        faces.extend_from_slice(&[3, 0, 1, 2]);
    }
    std::fs::write(d.join("faces.ply"), faces).unwrap();
    let gz = std::process::Command::new("gzip")
        .args(["-9", "-f", "faces.ply"])
        .current_dir(d)
        .status()
        .unwrap();
    assert!(gz.success());
    assert!(std::fs::metadata(d.join("faces.ply.gz")).unwrap().len() < 100_000);
    // One face of two million corners: 2 MB of file, two million triangles.
    let mut corners = head(1, "uint uchar");
    corners.extend_from_slice(&tri);
    corners.extend_from_slice(&2_000_000u32.to_le_bytes());
    corners.extend((0..2_000_000).map(|i| (i % 3) as u8));
    std::fs::write(d.join("corners.ply"), corners).unwrap();
    // A 4,000-triangle strip placed by 250 nodes: a million triangles from 48 KB of data.
    let n = 4_002;
    let pos: Vec<u8> = (0..n)
        .flat_map(|i| [(i / 2) as f32, (i % 2) as f32, 0.0])
        .flat_map(|c| c.to_le_bytes())
        .collect();
    std::fs::write(d.join("strip.bin"), &pos).unwrap();
    let nodes: Vec<String> = (0..250)
        .map(|i| format!(r#"{{"mesh": 0, "translation": [0, 0, {i}]}}"#))
        .collect();
    std::fs::write(
        d.join("placed.gltf"),
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "buffers": [{{"byteLength": {len}, "uri": "strip.bin"}}],
            "bufferViews": [{{"buffer": 0, "byteLength": {len}}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": {n}, "type": "VEC3"}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "mode": 5}}]}}],
            "nodes": [{}]}}"#,
            nodes.join(", "),
            len = pos.len()
        ),
    )
    .unwrap();
}

/// `gen --patches` streams: balls6's 114.8 million patches start arriving while the process
/// holds little more than the curve-mode scene (it grew to 23 GB before being killed); the
/// reader stopping early ends it quietly.
#[test]
fn gen_patches_streams_in_little_memory() {
    use std::io::Read;
    let mut child = std::process::Command::new(QUIVER)
        .args(["gen", "balls6", "--patches"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = vec![0u8; 4 << 20];
    child
        .stdout
        .as_mut()
        .unwrap()
        .read_exact(&mut first)
        .unwrap();
    let text = String::from_utf8_lossy(&first);
    assert!(text.starts_with("# balls6 (written by quiver)\n"));
    assert!(text.matches("\npp 3\n").count() > 10_000);
    // Peak memory so far, from the kernel's record of the running process.
    let status = std::fs::read_to_string(format!("/proc/{}/status", child.id())).unwrap();
    let hwm: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches(" kB").trim().parse().ok())
        .unwrap();
    assert!(hwm < 256 << 10, "{hwm} kB");
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(String::from_utf8_lossy(&out.stderr), "");
}

/// An NFF of more patches than its file system has room for is refused before writing
/// (balls2 at resolution 1000: 1.09 billion triangles, at least 41.7 GiB of text).
#[test]
fn gen_refuses_an_nff_larger_than_the_free_disk() {
    let shm = Path::new("/dev/shm");
    if !shm.is_dir() {
        return;
    }
    let out = shm.join(format!("quiver-test-{}.nff", std::process::id()));
    let (code, stdout, err, _) = run_measured(
        &[
            "gen",
            "balls2",
            "--patches",
            "--resolution",
            "1000",
            "-o",
            out.to_str().unwrap(),
        ],
        Path::new("."),
    );
    // Only meaningful where /dev/shm has less than that free (it holds half the RAM at most).
    if code == Some(2) {
        assert_eq!(stdout, "");
        assert!(
            err.contains("the NFF takes at least 41.7 GiB")
                && err.contains("free on its file system"),
            "{err}"
        );
    }
    assert!(!out.exists());
}

/// A file with more primitives than the run can hold stops being read where the count passes
/// the share of the limit left for it: one face line fanning into 2 million triangles, read
/// with 256 MB allowed, fails at that line without storing them.
#[test]
fn a_file_past_its_share_of_memory_stops_at_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut obj = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nf");
    for _ in 0..2_000_000 {
        obj.push_str(" 1 2 3");
    }
    obj.push('\n');
    std::fs::write(d.join("fan.obj"), obj).unwrap();
    let (code, out, err, peak) = run_measured(&["build", "fan.obj", "--max-memory", "256M"], d);
    assert_eq!(code, Some(2), "{err}");
    assert_eq!(out, "");
    assert!(
        err.starts_with("error: fan.obj: more than ")
            && err.contains(
                "primitives by line 4, more than this command can hold within the 256 MiB"
            ),
        "{err}"
    );
    assert!(peak < 96 << 20, "{peak} bytes");
    // With room for them, the same file loads.
    run("build fan.obj").current_dir(d).assert().success();
}

// ---------------------------------------------------------------------------------------
// Issue 49.

/// `render`'s eye rays that hit, from its JSON report.
fn eye_hits(dir: &Path, args: &str) -> u64 {
    render_report(dir, args)["rays"]["eye_hit"]
        .as_u64()
        .unwrap()
}

/// `quiver render ARGS` run in `dir` on one thread: its JSON report.
fn render_report(dir: &Path, args: &str) -> serde_json::Value {
    let json = dir.join("hits.json");
    run(&format!(
        "render {args} --threads 1 -o /dev/null --json {}",
        json.display()
    ))
    .current_dir(dir)
    .assert()
    .success();
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

/// `render --motion` (issue 53 point 6) traces each corner at 16 times by default: 16
/// (res + 1)² eye rays; at one time (time 0) the moving scene is where the static one is: it
/// traces the rays `--instanced` traces, with the same hits.
#[test]
fn render_motion_traces_each_corner_at_sixteen_times() {
    let dir = tempfile::tempdir().unwrap();
    let blurred = render_report(dir.path(), "balls1 --res 16 --motion");
    assert_eq!(blurred["rays"]["eye"], 16 * 17 * 17);
    let at_zero = render_report(dir.path(), "balls1 --res 16 --motion --time-samples 1");
    let still = render_report(dir.path(), "balls1 --res 16 --instanced");
    assert_eq!(at_zero["rays"], still["rays"]);
}

/// Item 1: a binary PLY element without properties claims instances of zero bytes; a count of
/// 10^12 ran for an hour and 2^64 - 1 never ended. Now nothing is looped over.
#[test]
fn a_property_less_ply_element_loads_at_once() {
    let dir = tempfile::tempdir().unwrap();
    for count in ["1000000000000", "18446744073709551615"] {
        let file = dir.path().join("z.ply");
        std::fs::write(
            &file,
            format!("ply\nformat binary_little_endian 1.0\nelement nothing {count}\nend_header\n"),
        )
        .unwrap();
        quiver()
            .args(["build", file.to_str().unwrap()])
            .timeout(std::time::Duration::from_secs(60))
            .assert()
            .success()
            .stdout(predicate::str::contains("objects              0"));
    }
}

/// Item 6: a sphere of radius 1e13 traced as an instance (`--instanced`) was accepted with a
/// zero inverse (glam's f32 determinant overflows) and never hit; it must hit what the same
/// scene flattened into patches hits (`--patches`, the flattened oracle).
#[test]
fn a_huge_instanced_sphere_is_hit_as_its_patches_are() {
    let dir = tempfile::tempdir().unwrap();
    // The eye three radii away, off the axis by a hundredth of a radius.
    for (r, eye) in [
        ("1e13", "1e11 2e11 3e13"),
        ("1e-13", "1e-15 2e-15 3e-13"),
        ("1e30", "1e28 2e28 3e30"),
    ] {
        std::fs::write(
            dir.path().join("big.nff"),
            format!(
                "v\nfrom {eye}\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0\nresolution 64 64\n\
                 f 1 1 1 1 0 0 0 1\ns 0 0 0 {r}\n"
            ),
        )
        .unwrap();
        let patches = eye_hits(dir.path(), "big.nff --res 64 --patches");
        let instanced = eye_hits(dir.path(), "big.nff --res 64 --instanced");
        assert!(patches > 1000, "radius {r}: {patches}");
        // The same triangles, met in object space instead of world space: only rays that
        // graze an edge may differ (f32 rounds them either way; before, all 0 hit).
        assert!(
            instanced.abs_diff(patches) <= patches / 200,
            "radius {r}: {instanced} against {patches}"
        );
    }
}

/// Item 12: a flat analytic cone (radius 1e6 to 0 over a height of 2, seen from just above)
/// lost 29% of its eye hits in curve mode to the cancellation of its discriminant; now every
/// eye ray hits it, as its geometry says, and as its patches nearly all do.
#[test]
fn a_flat_cone_hits_in_curve_mode_what_its_patches_hit() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("flat.nff"),
        "v\nfrom 0 10 0.001\nat 0 0 0\nup 0 0 1\nangle 90\nhither 0.001\nresolution 64 64\n\
         f 1 1 1 1 0 0 0 1\nc 0 -1 0 1e6 0 1 0 0\n",
    )
    .unwrap();
    // The view (a square of half-width 10 at the cone's height) lies far inside its radius of
    // 1e6: by its geometry, every eye ray meets the cone.
    let every = 65 * 65;
    let curves = eye_hits(dir.path(), "flat.nff --res 64");
    assert_eq!(curves, every);
    // The tessellation agrees but for a few rays through the seams at its apex.
    let patches = eye_hits(dir.path(), "flat.nff --res 64 --patches");
    assert!(patches + 16 >= every, "{patches}");
}

/// Item 8: `--drop-non-finite` on a PLY quad with a NaN corner drops its two triangles and
/// says 2 (it said 1).
#[test]
fn a_dropped_ply_quad_is_reported_as_two_primitives() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("q.ply");
    std::fs::write(
        &file,
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
         0 0 0\n1 0 0\n1 nan 0\n0 1 0\n4 0 1 2 3\n",
    )
    .unwrap();
    quiver()
        .args(["build", file.to_str().unwrap(), "--drop-non-finite"])
        .assert()
        .success()
        .stderr(predicate::str::contains("dropped 2 primitives"));
}

/// Item 9: `build` of an OBJ smaller than ~7e-38 failed in the refit timing (its nudged copy
/// overflowed to NaN); it builds, as `render` of it did.
#[test]
fn a_tiny_obj_builds() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("tiny.obj");
    std::fs::write(
        &file,
        "v 0 0 0\nv 1e-38 0 0\nv 0 1e-38 0\nv 3e-39 3e-39 1e-38\nf 1 2 3\nf 1 2 4\n",
    )
    .unwrap();
    quiver()
        .args(["build", file.to_str().unwrap()])
        .assert()
        .success()
        .stdout(predicate::str::contains("objects              2"));
}

/// Item 11: output names of 236 to 255 bytes failed because the temporary
/// `.NAME.quiver-PID-K.tmp` passed 255 bytes; they are written, and no temporary remains.
#[test]
fn output_names_up_to_255_bytes_are_written() {
    let dir = tempfile::tempdir().unwrap();
    for len in [230, 236, 245, 251, 255] {
        let name = format!("{}.json", "n".repeat(len - 5));
        run(&format!("build tetra1 --json {name}"))
            .current_dir(dir.path())
            .assert()
            .success();
        assert!(dir.path().join(&name).is_file(), "{len}");
    }
    let names = names(dir.path());
    assert_eq!(names.len(), 5, "{names:?}");
}

/// Item 11: with stdout closed (`>&-`) the table cannot be written: exit 2 and a message, not
/// exit 0 with the table lost.
#[test]
fn a_closed_stdout_is_an_error() {
    let out = std::process::Command::new("sh")
        .args(["-c", &format!("'{QUIVER}' build tetra1 >&-")])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("error: cannot write to stdout"), "{err}");
}

/// Item 11: a UTF-8 byte order mark at the start of an OBJ, NFF or PLY file is skipped.
#[test]
fn scene_files_may_start_with_a_byte_order_mark() {
    let dir = tempfile::tempdir().unwrap();
    let files = [
        ("b.obj", TRIANGLE_OBJ.to_string()),
        (
            "b.nff",
            "f 1 1 1 1 0 0 0 1\np 3\n0 0 0\n1 0 0\n0 1 0\n".to_string(),
        ),
        (
            "b.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
             end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
                .to_string(),
        ),
    ];
    for (name, text) in files {
        std::fs::write(dir.path().join(name), format!("\u{feff}{text}")).unwrap();
        run(&format!("build {name}"))
            .current_dir(dir.path())
            .assert()
            .success()
            .stdout(predicate::str::contains("objects              1"));
    }
}

/// Item 13: `--max-memory` errors say what was wrong with the value, and name the flag.
#[test]
fn max_memory_values_are_explained() {
    for (value, says) in [
        ("99999999T", "more than the 16 EiB"),
        ("-1", "is negative"),
        ("0", "less than 1 byte"),
    ] {
        quiver()
            .args(["build", "tetra1", "--max-memory", value])
            .assert()
            .code(2)
            .stderr(predicate::str::contains("--max-memory").and(predicate::str::contains(says)));
    }
    // A limit of 1 byte is shown as such, not as "1 KiB".
    quiver()
        .args(["build", "tetra1", "--max-memory", "1"])
        .assert()
        .code(2)
        .stderr(predicate::str::contains(
            "more than the 1 byte this run may use",
        ));
}

/// Item 13: a scene path that is not UTF-8 is refused naming the argument.
#[test]
fn a_non_utf8_argument_is_named() {
    use std::os::unix::ffi::OsStrExt as _;
    let bad = std::ffi::OsStr::from_bytes(b"sc\xffne.obj");
    quiver().arg("build").arg(bad).assert().code(2).stderr(
        predicate::str::contains("argument 2").and(predicate::str::contains("not valid UTF-8")),
    );
}

/// Item 3: a glTF buffer URI leading out of the glTF's folder (`../`, percent-encoded `/`) is
/// refused naming the URI, and nothing of the file outside is printed; `--outside-files`
/// allows it.
#[test]
fn gltf_buffers_outside_the_folder_are_refused_unless_allowed() {
    let root = tempfile::tempdir().unwrap();
    let inside = root.path().join("in");
    std::fs::create_dir(&inside).unwrap();
    let tri: Vec<u8> = [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    std::fs::write(root.path().join("secret.bin"), &tri).unwrap();
    let abs = root
        .path()
        .join("secret.bin")
        .to_str()
        .unwrap()
        .replace('/', "%2F");
    for uri in ["../secret.bin", abs.as_str()] {
        std::fs::write(
            inside.join("t.gltf"),
            format!(
                r#"{{"asset": {{"version": "2.0"}}, "buffers": [{{"byteLength": 36, "uri": "{uri}"}}],
                "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
                "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}}],
                "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}], "nodes": [{{"mesh": 0}}]}}"#
            ),
        )
        .unwrap();
        quiver()
            .args(["gen", "t.gltf"])
            .current_dir(&inside)
            .assert()
            .code(2)
            .stdout("")
            .stderr(
                predicate::str::contains(format!("buffers[0].uri: '{uri}'"))
                    .and(predicate::str::contains("--outside-files")),
            );
        quiver()
            .args(["gen", "t.gltf", "--outside-files"])
            .current_dir(&inside)
            .assert()
            .success();
    }
}
