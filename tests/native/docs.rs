//! The docs name files that exist: every repository path in `README.md`, `CONTRIBUTING.md`
//! and `docs/*.md` — a relative link, or a code span that starts with a top-level folder of
//! the repository (`src/…`, `tests/…`, …) or names a source file by a path relative to
//! `src/` (`fusion/lower.rs`) — is a file or folder of the repository. Braces expand
//! (`shims/{blas,lapack}/src/ffi.rs` is two paths) and `*` matches one name in a folder; a
//! trailing `:line` is dropped. Generated places — the folders `.gitignore` names
//! (`target/`, `www/docs/`, …), which a fresh clone does not have — and placeholders in
//! capitals (`OUT/shard-A.json`) are not paths of the repository.

use std::path::{Path, PathBuf};

/// Top-level folders of the repository: a code span starting with one is a path.
const ROOTS: [&str; 14] = [
    "src/",
    "tests/",
    "scripts/",
    "docs/",
    "www/",
    "python/",
    "npm/",
    "cli/",
    "shims/",
    "examples/",
    "configs/",
    "benches/",
    ".ci/",
    ".cargo/",
];

/// Extensions of the files a path relative to `src/` may name.
const SOURCE: [&str; 12] = [
    ".rs", ".py", ".pyi", ".sh", ".mjs", ".js", ".md", ".toml", ".json", ".html", ".css", ".ts",
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `a/{b,c}/d` → `a/b/d`, `a/c/d` (nested and repeated braces too).
fn expand(path: &str) -> Vec<String> {
    let Some(open) = path.find('{') else {
        return vec![path.to_string()];
    };
    let Some(close) = path[open..].find('}').map(|c| open + c) else {
        return vec![path.to_string()];
    };
    path[open + 1..close]
        .split(',')
        .flat_map(|alt| expand(&format!("{}{alt}{}", &path[..open], &path[close + 1..])))
        .collect()
}

/// Whether `path` (relative to `base`, `*` matching one name) exists.
fn exists(base: &Path, path: &str) -> bool {
    let mut candidates = vec![base.to_path_buf()];
    for part in path.trim_end_matches('/').split('/') {
        candidates = candidates
            .into_iter()
            .flat_map(|dir| -> Vec<PathBuf> {
                match part {
                    "" | "." => vec![dir],
                    ".." => vec![dir.parent().map_or(dir.clone(), Path::to_path_buf)],
                    _ if part.contains('*') => {
                        let (prefix, suffix) = part.split_once('*').unwrap_or((part, ""));
                        std::fs::read_dir(&dir)
                            .into_iter()
                            .flatten()
                            .flatten()
                            .filter(|e| {
                                let name = e.file_name().to_string_lossy().into_owned();
                                name.starts_with(prefix) && name.ends_with(suffix)
                            })
                            .map(|e| e.path())
                            .collect()
                    }
                    _ => vec![dir.join(part)],
                }
            })
            .collect();
    }
    candidates.iter().any(|p| p.exists())
}

/// The folders the repository ignores (`.gitignore`'s lines ending in `/`): generated, so
/// not in a fresh clone.
fn generated() -> Vec<String> {
    let ignore = std::fs::read_to_string(root().join(".gitignore")).unwrap_or_default();
    ignore
        .lines()
        .map(str::trim)
        .filter(|l| l.ends_with('/') && !l.starts_with('#'))
        .map(|l| l.trim_start_matches('/').to_string())
        .collect()
}

/// The repository paths `text` (the file `doc`) names, with their line numbers, each as the
/// candidates it may be relative to.
fn named_paths(doc: &Path, text: &str) -> Vec<(usize, String, Vec<PathBuf>)> {
    let root = root();
    let folder = doc.parent().unwrap_or(&root).to_path_buf();
    let generated = generated();
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        // Relative links: `](path)` not to a web address or an anchor.
        for (at, _) in line.match_indices("](") {
            let rest = &line[at + 2..];
            let target = rest.split([')', ' ']).next().unwrap_or("");
            let target = target.split('#').next().unwrap_or("");
            if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            out.push((i + 1, target.to_string(), vec![folder.clone()]));
        }
        // Code spans.
        for (k, span) in line.split('`').enumerate() {
            if k % 2 == 0 || span.contains(char::is_whitespace) {
                continue;
            }
            let span = span.trim_end_matches(['.', ',', ':', ';']);
            let span = match span.rsplit_once(':') {
                Some((path, line)) if line.chars().all(|c| c.is_ascii_digit()) => path,
                _ => span,
            };
            let placeholder = span
                .split('/')
                .any(|p| p.len() > 1 && p.chars().all(|c| c.is_ascii_uppercase()));
            let ignored = generated.iter().any(|g| span.starts_with(g.as_str()));
            if placeholder || ignored || span.starts_with(['/', '~']) || span.contains("://") {
                continue;
            }
            if ROOTS.iter().any(|r| span.starts_with(r)) {
                out.push((i + 1, span.to_string(), vec![root.clone()]));
            } else if span.contains('/') && SOURCE.iter().any(|e| span.ends_with(e)) {
                let bases = vec![root.clone(), root.join("src"), folder.clone()];
                out.push((i + 1, span.to_string(), bases));
            }
        }
    }
    out
}

#[test]
fn every_path_the_docs_name_exists() {
    let root = root();
    let mut docs = vec![root.join("README.md"), root.join("CONTRIBUTING.md")];
    let mut in_docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    in_docs.sort();
    docs.extend(in_docs);
    let mut missing = Vec::new();
    let mut checked = 0;
    for doc in &docs {
        let text = std::fs::read_to_string(doc).unwrap();
        for (line, path, bases) in named_paths(doc, &text) {
            for one in expand(&path) {
                checked += 1;
                if !bases.iter().any(|b| exists(b, &one)) {
                    let doc = doc.strip_prefix(&root).unwrap_or(doc).display();
                    missing.push(format!("{doc}:{line}: {one}"));
                }
            }
        }
    }
    assert!(
        checked > 100,
        "only {checked} paths found: is the scan broken?"
    );
    assert!(
        missing.is_empty(),
        "paths named in the docs that do not exist:\n{}",
        missing.join("\n")
    );
}

/// The scan itself: a path that does not exist is reported, braces expand, a trailing line
/// number and generated places are left out.
#[test]
fn the_path_scan_finds_what_it_should() {
    let root = root();
    let doc = root.join("docs/example.md");
    let text = "see `src/nowhere.rs:12`, `shims/{blas,lapack}/src/ffi.rs`, [guide](rust.md), \
                `target/py`, `www/docs/`, `OUT/shard-A.json` and `fusion/lower.rs`.";
    let found = named_paths(&doc, text);
    let names: Vec<&str> = found.iter().map(|(_, p, _)| p.as_str()).collect();
    assert_eq!(
        names,
        [
            "rust.md",
            "src/nowhere.rs",
            "shims/{blas,lapack}/src/ffi.rs",
            "fusion/lower.rs"
        ]
    );
    let ok = |k: usize, p: &str| found[k].2.iter().any(|b| exists(b, p));
    assert!(ok(0, "rust.md"));
    assert!(!ok(1, "src/nowhere.rs"));
    let both = expand("shims/{blas,lapack}/src/ffi.rs");
    assert_eq!(both, ["shims/blas/src/ffi.rs", "shims/lapack/src/ffi.rs"]);
    assert!(both.iter().all(|p| ok(2, p)));
    assert!(ok(3, "fusion/lower.rs"));
    assert!(exists(&root, "shims/*/src/ffi.rs") && !exists(&root, "shims/*/src/none.rs"));
    let generated = generated();
    assert!(["target/", "www/docs/", "test-output/"]
        .iter()
        .all(|g| generated.iter().any(|x| x == g)));
}
