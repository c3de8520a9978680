//! `include/quiver.h` and the library declare the same functions: every `qv_*(` the header
//! declares is a `#[no_mangle]` function in `src/`, and every such function is declared.
//! The status codes carry the same names and numbers on both sides. The header is written by
//! hand, so this is what keeps the two from drifting apart.

use std::collections::BTreeSet;
use std::path::Path;

/// `text` without its C comments (`/* */` and `//`).
fn strip_c_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    loop {
        let block = rest.find("/*");
        let line = rest.find("//");
        match (block, line) {
            (Some(b), l) if l.is_none_or(|l| b < l) => {
                out.push_str(&rest[..b]);
                let end = rest[b + 2..]
                    .find("*/")
                    .expect("an unclosed comment in quiver.h");
                rest = &rest[b + 2 + end + 2..];
            }
            (_, Some(l)) => {
                out.push_str(&rest[..l]);
                rest = rest[l..].find('\n').map_or("", |n| &rest[l + n..]);
            }
            (_, None) => {
                out.push_str(rest);
                return out;
            }
        }
    }
}

/// The names `qv_*` followed by `(` in `code`: the functions a C header declares.
fn declared(code: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let mut from = 0;
    while let Some(at) = code[from..].find("qv_") {
        let start = from + at;
        let ident_before = code[..start]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_alphanumeric() || c == '_');
        let len = code[start..]
            .find(|c: char| !(c.is_alphanumeric() || c == '_'))
            .unwrap_or(code.len() - start);
        let name = &code[start..start + len];
        if !ident_before && code[start + len..].trim_start().starts_with('(') {
            names.insert(name.to_string());
        }
        from = start + len;
    }
    names
}

/// The `#[no_mangle]` functions of the Rust sources in `dir`: the symbols the library exports.
fn exported(dir: &Path) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "rs") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        // The attribute on a line of its own (not a mention in a comment), then the next
        // `fn NAME(` after it (other attributes may come between).
        let lines: Vec<&str> = text.lines().collect();
        for (i, _) in lines
            .iter()
            .enumerate()
            .filter(|(_, l)| l.trim() == "#[no_mangle]")
        {
            let after = lines[i..].join("\n");
            let f = after.find("fn ").expect("#[no_mangle] on a function");
            let name: String = after[f + 3..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            assert!(
                name.starts_with("qv_"),
                "{}: {name} is not named qv_*",
                path.display()
            );
            names.insert(name);
        }
    }
    names
}

#[test]
fn the_header_declares_exactly_the_exported_functions() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let header = std::fs::read_to_string(root.join("include/quiver.h")).unwrap();
    let in_header = declared(&strip_c_comments(&header));
    let in_library = exported(&root.join("src"));
    let missing: Vec<_> = in_library.difference(&in_header).collect();
    let extra: Vec<_> = in_header.difference(&in_library).collect();
    assert!(
        missing.is_empty(),
        "exported but not in quiver.h: {missing:?}"
    );
    assert!(extra.is_empty(), "in quiver.h but not exported: {extra:?}");
    assert!(in_library.len() >= 25, "{in_library:?}");
}

#[test]
fn the_parsers_see_what_they_should() {
    let c = "/* qv_not(a) */ int qv_a(void); // qv_b(x)\nvoid qv_c (int);\n#define QV_X qv_d\nxqv_e(1);";
    let names = declared(&strip_c_comments(c));
    assert_eq!(names.into_iter().collect::<Vec<_>>(), ["qv_a", "qv_c"]);
}

/// The C name of a status (an exhaustive match: a new status fails to compile here until it
/// is named, and then [`STATUSES`] and the header's check follow).
fn c_name(s: quiver_capi::QvStatus) -> &'static str {
    use quiver_capi::QvStatus::*;
    match s {
        Ok => "QV_OK",
        NullPointer => "QV_NULL_POINTER",
        InvalidArgument => "QV_INVALID_ARGUMENT",
        BadMesh => "QV_BAD_MESH",
        Io => "QV_IO",
        BadFile => "QV_BAD_FILE",
        Panic => "QV_PANIC",
    }
}

/// Every status.
const STATUSES: [quiver_capi::QvStatus; 7] = {
    use quiver_capi::QvStatus::*;
    [
        Ok,
        NullPointer,
        InvalidArgument,
        BadMesh,
        Io,
        BadFile,
        Panic,
    ]
};

#[test]
fn the_header_numbers_the_statuses_as_the_library_does() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let header = strip_c_comments(&std::fs::read_to_string(root.join("include/quiver.h")).unwrap());
    let body = header
        .split("typedef enum QvStatus {")
        .nth(1)
        .and_then(|rest| rest.split('}').next())
        .expect("quiver.h declares enum QvStatus");
    let in_header: Vec<(String, i64)> = body
        .split(',')
        .filter(|e| !e.trim().is_empty())
        .map(|e| {
            let (name, value) = e
                .split_once('=')
                .expect("each status has its value written");
            (name.trim().to_string(), value.trim().parse().unwrap())
        })
        .collect();
    let in_library: Vec<(String, i64)> = STATUSES
        .iter()
        .map(|&s| (c_name(s).to_string(), s as i64))
        .collect();
    assert_eq!(in_header, in_library);
}
