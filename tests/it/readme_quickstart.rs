//! The README's commands run as written, and every link of the README and the docs resolves
//! (issue 12: a newcomer's first hour). The quick start's `cargo run --release -- ARGS` lines and
//! the round trip under "Commands" run with the built binary in a scratch folder holding a copy
//! of `examples/`, so their outputs land there and not in the repository.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// The `harmonid` arguments of every `cargo run --release -- ARGS` command in the ```sh blocks
/// of `text` (backslash continuations joined).
fn cargo_run_commands(text: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut in_sh = false;
    let mut line = String::new();
    for raw in text.lines() {
        if raw.starts_with("```") {
            in_sh = raw == "```sh";
            continue;
        }
        if !in_sh {
            continue;
        }
        let part = raw.trim();
        if let Some(head) = part.strip_suffix('\\') {
            line.push_str(head);
            line.push(' ');
            continue;
        }
        line.push_str(part);
        let cmd = line.split('#').next().unwrap_or("").trim().to_string();
        line.clear();
        if let Some(args) = cmd.strip_prefix("cargo run --release -- ") {
            out.push(args.split_whitespace().map(String::from).collect());
        }
    }
    out
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for e in std::fs::read_dir(from).expect("read_dir") {
        let e = e.expect("entry");
        let dest = to.join(e.file_name());
        if e.file_type().expect("file type").is_dir() {
            copy_dir(&e.path(), &dest);
        } else {
            std::fs::copy(e.path(), dest).expect("copy");
        }
    }
}

#[test]
fn the_readme_commands_run_as_written() {
    let readme = read("README.md");
    let commands = cargo_run_commands(&readme);
    // The main command, and the round trip (simulate, then identify what it wrote).
    assert!(commands.len() >= 3, "{commands:?}");
    assert_eq!(
        commands[0][..3],
        [
            "identify",
            "examples/nanostring_2mode/model.hb",
            "examples/nanostring_2mode/data"
        ]
    );
    assert!(readme.contains("cargo test --release --workspace"));
    let scratch = tempfile::tempdir().expect("tempdir");
    copy_dir(&root().join("examples"), &scratch.path().join("examples"));
    for args in &commands {
        let out = Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .current_dir(scratch.path())
            .args(args)
            .output()
            .expect("run harmonid");
        assert!(
            out.status.success(),
            "harmonid {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
        if let Some(i) = args.iter().position(|a| a == "--out") {
            assert!(scratch.path().join(&args[i + 1]).exists(), "{args:?}");
        }
    }
    let result = std::fs::read_to_string(scratch.path().join("result.json")).expect("result");
    assert!(result.contains("\"format\": \"harmonid-result/1\""));
    // The install section's check.
    assert!(
        readme.contains("cargo install --locked --path .") && readme.contains("harmonid --help")
    );
    let help = Command::new(env!("CARGO_BIN_EXE_harmonid"))
        .arg("--help")
        .output()
        .expect("run harmonid --help");
    assert!(help.status.success());
    assert!(String::from_utf8_lossy(&help.stdout).contains("identify"));
}

#[test]
fn the_readme_outputs_are_ignored_by_git() {
    let ignore = read(".gitignore");
    for out in [
        "/result.json",
        "/my_data/",
        "/shots.csv",
        "/study.csv",
        "/curve.csv",
    ] {
        assert!(ignore.lines().any(|l| l == out), ".gitignore lacks {out}");
    }
}

/// GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The lines of a markdown text outside fenced code blocks.
fn prose_lines(markdown: &str) -> Vec<&str> {
    let mut in_code = false;
    markdown
        .lines()
        .filter(|l| {
            if l.starts_with("```") {
                in_code = !in_code;
                return false;
            }
            !in_code
        })
        .collect()
}

fn anchors(markdown: &str) -> Vec<String> {
    prose_lines(markdown)
        .into_iter()
        .filter(|l| l.starts_with('#'))
        .map(|l| slug(l.trim_start_matches('#')))
        .collect()
}

/// Every `](target)` of a markdown text, outside fenced code.
fn links(markdown: &str) -> Vec<String> {
    let mut v = Vec::new();
    for l in prose_lines(markdown) {
        let mut rest = l;
        while let Some(i) = rest.find("](") {
            let tail = &rest[i + 2..];
            let Some(j) = tail.find(')') else { break };
            v.push(tail[..j].to_string());
            rest = &tail[j..];
        }
    }
    v
}

fn markdown_pages() -> Vec<String> {
    let mut pages = vec!["README.md".to_string(), "tests/data/README.md".to_string()];
    for dir in ["docs", "examples"] {
        for e in std::fs::read_dir(root().join(dir)).expect("read_dir") {
            let p = e.expect("entry").path();
            let page = if p.is_dir() { p.join("README.md") } else { p };
            if page.extension().is_some_and(|x| x == "md") && page.exists() {
                let rel = page.strip_prefix(root()).expect("inside the repository");
                pages.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    pages.sort();
    pages
}

#[test]
fn every_link_of_the_readme_and_the_docs_resolves() {
    let pages = markdown_pages();
    assert!(
        pages.contains(&"docs/data-format.md".to_string()),
        "{pages:?}"
    );
    let mut checked = 0;
    for page in &pages {
        let text = read(page);
        // Nothing a clone lacks: the shared workspace is not part of the repository (the README
        // may say what .ci/check-shared-data compares, but no page sends a reader there).
        for lacking in [
            "../shared/DATA_FORMAT",
            "../shared/STYLE",
            "../shared/paper",
        ] {
            assert!(!text.contains(lacking), "{page} refers to {lacking}");
        }
        let dir = Path::new(page).parent().expect("parent");
        for link in links(&text) {
            if link.contains("://") || link.starts_with("mailto:") {
                continue;
            }
            assert!(
                !link.contains("shared/"),
                "{page}: link {link} leaves the repository"
            );
            let (path, anchor) = match link.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (link.as_str(), None),
            };
            let target = if path.is_empty() {
                PathBuf::from(page)
            } else {
                dir.join(path)
            };
            let full = root().join(&target);
            assert!(
                full.exists(),
                "{page}: link {link} → {} is missing",
                target.display()
            );
            if let Some(a) = anchor {
                let md = std::fs::read_to_string(&full).expect("linked page");
                assert!(
                    anchors(&md).iter().any(|x| x == a),
                    "{page}: no anchor #{a} in {}",
                    target.display()
                );
            }
            checked += 1;
        }
        // Every page but the data-format page itself links to it.
        if page.starts_with("docs/") && page != "docs/data-format.md" || page == "README.md" {
            assert!(
                text.contains("data-format.md"),
                "{page} does not link docs/data-format.md"
            );
        }
    }
    println!("{checked} links in {} pages", pages.len());
    assert!(checked >= 10, "{checked}");
}

/// The README's layout table names every crate of the workspace (it once left out `crates/plan`).
#[test]
fn readme_layout_lists_every_crate() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README");
    let mut crates: Vec<String> = std::fs::read_dir(root.join("crates"))
        .expect("crates/")
        .filter_map(Result::ok)
        .filter(|e| e.path().join("Cargo.toml").is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    crates.sort();
    assert!(crates.len() >= 10, "{crates:?}");
    for c in &crates {
        assert!(
            readme.contains(&format!("| `crates/{c}` |")),
            "README.md's layout table has no row for crates/{c}"
        );
    }
}
