//! Golden replay tests that always run: small inputs committed under `tests/data/` (made
//! by the project's simulator, `compass-pdr simulate`, or written from each format's
//! public description; never copies of `../shared/data`), each case of
//! `tests/data/cases.txt` run through the `compass-pdr` binary and its whole output
//! (exit code, stdout, stderr, and the files it writes) compared with
//! `tests/data/expected/NAME.expected`. After a deliberate change, refresh them with
//!
//!   UPDATE_EXPECT=1 cargo test --test golden
//!
//! and read the diff before committing it (rust-analyzer's `expect-test` habit).

use std::path::{Path, PathBuf};
use std::process::Command;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("data")
}

/// One case's arguments: split on spaces, except that an argument after `--map` is the
/// rest of the line (column names have spaces).
fn arguments(line: &str, out_dir: &Path) -> Vec<String> {
    let line = line.replace("$OUT", &out_dir.display().to_string());
    match line.split_once("--map ") {
        Some((before, map)) => {
            let mut args: Vec<String> = before.split_whitespace().map(str::to_string).collect();
            args.push("--map".to_string());
            args.push(map.trim().to_string());
            args
        }
        None => line.split_whitespace().map(str::to_string).collect(),
    }
}

/// What a written file contributes to the record: text as it is, anything else in hex.
fn describe_file(path: &Path) -> String {
    let bytes = std::fs::read(path).expect("a written file is readable");
    match String::from_utf8(bytes.clone()) {
        Ok(text) => text,
        Err(_) => {
            bytes
                .chunks(16)
                .map(|chunk| {
                    chunk
                        .iter()
                        .map(|b| format!("{b:02x}"))
                        .collect::<Vec<_>>()
                        .join(" ")
                })
                .collect::<Vec<_>>()
                .join("\n")
                + "\n"
        }
    }
}

/// `html` without its `<block …>…</block>` elements.
fn without_blocks(html: &str, block: &str) -> String {
    let (open, close) = (format!("<{block}"), format!("</{block}>"));
    let mut kept = String::new();
    let mut rest = html;
    while let Some(start) = rest.find(&open) {
        kept.push_str(&rest[..start]);
        rest = rest[start..]
            .find(&close)
            .map_or("", |end| &rest[start + end + close.len()..]);
    }
    kept.push_str(rest);
    kept
}

/// The text a reader sees in an HTML report: `<svg>`, `<style>` and `<script>` blocks
/// left out, tags removed, one line per non-empty line.
fn html_text(html: &str) -> String {
    let mut rest = html.to_string();
    for block in ["svg", "style", "script"] {
        rest = without_blocks(&rest, block);
    }
    let mut plain = String::new();
    let mut in_tag = false;
    for c in rest.chars() {
        match c {
            '<' => in_tag = true,
            '>' if in_tag => {
                in_tag = false;
                plain.push(' ');
            }
            _ if !in_tag => plain.push(c),
            _ => {}
        }
    }
    plain
        .lines()
        .map(|line| line.split_whitespace().collect::<Vec<_>>().join(" "))
        .filter(|line| !line.is_empty())
        .map(|line| line + "\n")
        .collect()
}

/// Runs one case and returns its record, the temporary folder's path written as `$OUT`.
fn run(name: &str, line: &str) -> String {
    let out_dir =
        std::env::temp_dir().join(format!("compass-pdr-golden-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out_dir);
    std::fs::create_dir_all(&out_dir).expect("a temporary folder");
    let output = Command::new(env!("CARGO_BIN_EXE_compass-pdr"))
        .args(arguments(line, &out_dir))
        .current_dir(data())
        .env_remove("XDG_CONFIG_HOME")
        .env("HOME", &out_dir)
        .output()
        .expect("the binary runs");
    let out_text = out_dir.display().to_string();
    let mut record = format!(
        "$ compass-pdr {line}\nexit: {}\n--- stdout\n{}--- stderr\n{}",
        output
            .status
            .code()
            .map_or("signal".to_string(), |code| code.to_string()),
        String::from_utf8_lossy(&output.stdout).replace(&out_text, "$OUT"),
        String::from_utf8_lossy(&output.stderr).replace(&out_text, "$OUT"),
    );
    let mut written: Vec<PathBuf> = std::fs::read_dir(&out_dir)
        .expect("the temporary folder")
        .filter_map(|entry| entry.ok().map(|entry| entry.path()))
        .filter(|path| path.is_file())
        .collect();
    written.sort();
    for path in written {
        let file_name = path
            .file_name()
            .map(|name| name.to_string_lossy().to_string())
            .unwrap_or_default();
        if path.extension().is_some_and(|ext| ext == "html") {
            // The report's figures are SVG by the hundred kilobytes: its words stand for it.
            record.push_str(&format!(
                "--- file {file_name} (its text, without the figures and styles)\n{}",
                html_text(&describe_file(&path))
            ));
        } else {
            record.push_str(&format!("--- file {file_name}\n{}", describe_file(&path)));
        }
    }
    let _ = std::fs::remove_dir_all(&out_dir);
    record
}

/// `actual` against the file `expect`; with `UPDATE_EXPECT=1`, `expect` is rewritten.
fn check(actual: &str, expect: &Path) -> Result<(), String> {
    if std::env::var_os("UPDATE_EXPECT").is_some() {
        std::fs::write(expect, actual).expect("the expected file can be written");
        return Ok(());
    }
    let expected = std::fs::read_to_string(expect).unwrap_or_default();
    if expected == actual {
        return Ok(());
    }
    let first_difference = expected
        .lines()
        .zip(actual.lines())
        .position(|(a, b)| a != b)
        .unwrap_or(expected.lines().count().min(actual.lines().count()));
    Err(format!(
        "{} differs from line {} on:\n  expected: {:?}\n  actual:   {:?}\n(UPDATE_EXPECT=1 cargo test --test golden rewrites it; read the diff)",
        expect.display(),
        first_difference + 1,
        expected.lines().nth(first_difference).unwrap_or("<end>"),
        actual.lines().nth(first_difference).unwrap_or("<end>"),
    ))
}

#[test]
fn every_golden_case_gives_its_expected_output() {
    let cases = std::fs::read_to_string(data().join("cases.txt")).expect("tests/data/cases.txt");
    let expected_dir = data().join("expected");
    std::fs::create_dir_all(&expected_dir).expect("tests/data/expected");
    let mut failures = Vec::new();
    let mut n_cases = 0;
    for line in cases
        .lines()
        .map(str::trim)
        .filter(|line| !line.is_empty() && !line.starts_with('#'))
    {
        let (name, command) = line.split_once(':').expect("`name: arguments`");
        n_cases += 1;
        let record = run(name.trim(), command.trim());
        if let Err(message) = check(
            &record,
            &expected_dir.join(format!("{}.expected", name.trim())),
        ) {
            failures.push(message);
        }
    }
    assert!(n_cases >= 20, "only {n_cases} cases");
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The committed canonical CSV is exactly what the simulator writes for its seed, so the
/// golden inputs can be remade rather than trusted.
#[test]
fn the_golden_walk_is_the_simulator_s_output() {
    let out_dir =
        std::env::temp_dir().join(format!("compass-pdr-golden-sim-{}", std::process::id()));
    std::fs::create_dir_all(&out_dir).expect("a temporary folder");
    for (file, extra) in [
        ("walk.csv", &[][..]),
        ("walk.nmea", &[][..]),
        ("dance.txt", &["--scenario", "dance"][..]),
    ] {
        let seed = if file == "dance.txt" { "2" } else { "3" };
        let status = Command::new(env!("CARGO_BIN_EXE_compass-pdr"))
            .args(["simulate", "--seed", seed, "--duration-s", "12", "--out"])
            .arg(out_dir.join(file))
            .args(extra)
            .output()
            .expect("the binary runs");
        assert!(
            status.status.success(),
            "{}",
            String::from_utf8_lossy(&status.stderr)
        );
        let made = std::fs::read(out_dir.join(file)).expect("written");
        let committed = std::fs::read(data().join(file)).expect("committed");
        assert!(made == committed, "tests/data/{file} is not what `compass-pdr simulate --seed {seed} --duration-s 12 {}` writes", extra.join(" "));
    }
    let _ = std::fs::remove_dir_all(&out_dir);
}
