//! docs/ARCHITECTURE.md's invariants that the source text itself can show, checked on the
//! crate's own files (always present, so these run in every clone):
//!
//! - the core (everything outside `src/web/`, `src/cli/` and `src/main.rs`) reads no
//!   clock, file, environment variable, argv or standard stream, and knows nothing of
//!   the browser (wasm-bindgen, web-sys, js-sys, gloo, plotters-canvas);
//! - the layer table of docs/ARCHITECTURE.md is the import graph: each top-level module
//!   imports only the rows below its own, and `src/` holds folders and at most three
//!   loose files;
//! - no function is over 120 lines, no file over 800 without its tests (nor 1,000 with).
//!
//! Only code is read: comments are skipped, and so is test code (a `tests.rs` file, a
//! `#[cfg(test)] mod …;` declaration, and a file's lines from an inline `#[cfg(test)]`
//! module on), which may use the simulator or read `../shared/data`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What the core must not name.
const NOT_IN_THE_CORE: [&str; 17] = [
    "std::fs",
    "std::time",
    "Instant::",
    "SystemTime",
    "std::env",
    "std::process",
    "std::io::stdout",
    "std::io::stdin",
    "println!",
    "print!(",
    "eprintln!",
    "eprint!(",
    "wasm_bindgen",
    "web_sys",
    "js_sys",
    "gloo",
    "plotters_canvas",
];

fn rust_files(dir: &Path, files: &mut Vec<PathBuf>) {
    let entries = std::fs::read_dir(dir).expect("the source folder is readable");
    for entry in entries {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            rust_files(&path, files);
        } else if path.extension().is_some_and(|ext| ext == "rs") {
            files.push(path);
        }
    }
}

/// The file's code lines (1-based line numbers), without comments and without tests.
fn code_lines(path: &Path) -> Vec<(usize, String)> {
    if path.file_name().is_some_and(|name| name == "tests.rs") {
        return Vec::new();
    }
    let text = std::fs::read_to_string(path).expect("a source file is UTF-8");
    let mut lines = Vec::new();
    let all: Vec<&str> = text.lines().collect();
    let mut skip_next = false;
    for (idx, line) in all.iter().enumerate() {
        let trimmed = line.trim_start();
        if skip_next {
            skip_next = false;
            continue;
        }
        if trimmed.starts_with("#[cfg(test)]") {
            // `#[cfg(test)] mod tests;` declares a test file (read no further there); an
            // inline test module runs to the end of the file.
            let declares_a_file = all.get(idx + 1).is_some_and(|next| {
                next.trim_start().starts_with("mod ") && next.trim_end().ends_with(';')
            });
            if declares_a_file {
                skip_next = true;
                continue;
            }
            break;
        }
        if trimmed.starts_with("//") {
            continue;
        }
        // A trailing comment is not code either (a `//` inside a string is rare enough
        // in this crate to ignore: it would only hide a violation, never invent one).
        let code = match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        };
        lines.push((idx + 1, code.to_string()));
    }
    lines
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn the_core_reads_no_clock_file_environment_or_stream_and_knows_no_browser() {
    let src = src();
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let edges = [src.join("web"), src.join("cli"), src.join("main.rs")];
    let mut violations = Vec::new();
    for path in files
        .iter()
        .filter(|path| !edges.iter().any(|edge| path.starts_with(edge)))
    {
        for (line_no, code) in code_lines(path) {
            for name in NOT_IN_THE_CORE {
                if code.contains(name) {
                    violations.push(format!(
                        "{}:{line_no}: {name}",
                        path.strip_prefix(&src).unwrap_or(path).display()
                    ));
                }
            }
        }
    }
    assert!(
        files.len() > 50,
        "the source was not found ({} files)",
        files.len()
    );
    assert!(violations.is_empty(), "{violations:#?}");
}

/// The functions of the crate's code longer than `max_lines` (from the `fn` line to its
/// closing brace), as `path:line name length`. Braces are counted outside comments and
/// character literals; format strings' braces come in pairs.
fn long_functions(max_lines: usize) -> Vec<(String, usize)> {
    let src = src();
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut long = Vec::new();
    for path in &files {
        let lines = code_lines(path);
        let mut idx = 0;
        while idx < lines.len() {
            let (line_no, code) = &lines[idx];
            let trimmed = code.trim_start();
            let after_qualifiers = trimmed
                .trim_start_matches("pub(crate) ")
                .trim_start_matches("pub(super) ")
                .trim_start_matches("pub ")
                .trim_start_matches("const ")
                .trim_start_matches("async ")
                .trim_start_matches("unsafe ");
            let Some(signature) = after_qualifiers.strip_prefix("fn ") else {
                idx += 1;
                continue;
            };
            let name: String = signature
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let (mut depth, mut opened, mut end) = (0i64, false, None);
            'lines: for (offset, (end_line_no, text)) in lines[idx..].iter().enumerate() {
                let mut chars = text.chars().peekable();
                while let Some(c) = chars.next() {
                    match c {
                        '\'' => {
                            // A character literal such as '{' (a lifetime has no closing quote soon).
                            let rest: String = chars.clone().take(3).collect();
                            if rest.len() >= 2 && rest.chars().nth(1) == Some('\'') {
                                chars.next();
                                chars.next();
                            }
                        }
                        '{' => {
                            depth += 1;
                            opened = true;
                        }
                        '}' => depth -= 1,
                        ';' if !opened && depth == 0 => break 'lines,
                        _ => {}
                    }
                    if opened && depth == 0 {
                        end = Some((offset, *end_line_no));
                        break 'lines;
                    }
                }
            }
            if let Some((offset, end_line_no)) = end {
                let length = end_line_no - line_no + 1;
                if length > max_lines {
                    long.push((
                        format!(
                            "{}:{line_no} {name}",
                            path.strip_prefix(&src).unwrap_or(path).display()
                        ),
                        length,
                    ));
                }
                // Nested functions are counted inside their parent only.
                idx += offset + 1;
            } else {
                idx += 1;
            }
        }
    }
    long
}

/// No function over 120 lines: a function longer is split into its steps.
#[test]
fn no_function_is_over_120_lines() {
    const KNOWN: [(&str, usize); 0] = [];
    let mut violations = Vec::new();
    for (place, length) in long_functions(120) {
        let (file, rest) = place.split_once(':').unwrap_or((&place, ""));
        let name = rest.split_once(' ').map_or("", |(_, name)| name);
        let key = format!("{file} {name}");
        match KNOWN.iter().find(|(known, _)| *known == key) {
            Some(&(_, max)) if length <= max => {}
            Some(&(_, max)) => {
                violations.push(format!("{place}: {length} lines, more than its {max}"));
            }
            None => violations.push(format!("{place}: {length} lines")),
        }
    }
    assert!(violations.is_empty(), "{violations:#?}");
}

/// Lines of a file before its inline test module (a `#[cfg(test)] mod tests;` declaring
/// a test file does not end it), and in all.
fn file_lengths(path: &Path) -> (usize, usize) {
    let text = std::fs::read_to_string(path).expect("a source file is UTF-8");
    let all: Vec<&str> = text.lines().collect();
    let inline_tests = all.iter().enumerate().position(|(idx, line)| {
        line.trim_start().starts_with("#[cfg(test)]")
            && !all.get(idx + 1).is_some_and(|next| {
                next.trim_start().starts_with("mod ") && next.trim_end().ends_with(';')
            })
    });
    let without_tests = if path.file_name().is_some_and(|name| name == "tests.rs") {
        0
    } else {
        inline_tests.unwrap_or(all.len())
    };
    (without_tests, all.len())
}

/// Rooms a newcomer can hold in their head: no source file over 1,000 lines with its
/// tests, nor over 800 without them. A file that must be split later would be listed
/// with its present lengths, which may only shrink; none is.
#[test]
fn no_file_is_over_1000_lines_or_800_without_its_tests() {
    const BEING_SPLIT: [(&str, usize, usize); 0] = [];
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut violations = Vec::new();
    for path in files {
        let (without_tests, all) = file_lengths(&path);
        let name = path
            .strip_prefix(src())
            .unwrap_or(&path)
            .to_string_lossy()
            .replace('\\', "/");
        let (max_without, max_all) = BEING_SPLIT
            .iter()
            .find(|(known, _, _)| *known == name)
            .map_or((800, 1000), |&(_, without, all)| (without, all));
        if without_tests > max_without || all > max_all {
            violations.push(format!(
                "{name}: {without_tests} lines without its tests, {all} in all"
            ));
        }
    }
    assert!(violations.is_empty(), "{violations:#?}");
}

/// Each top-level module of `src/` and the modules it imports outside tests (`crate::…`
/// paths), with the first place each import is made.
fn imports_by_module() -> BTreeMap<String, BTreeMap<String, String>> {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut imports: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for path in &files {
        let relative = path.strip_prefix(src()).unwrap_or(path);
        let Some(first) = relative.components().next() else {
            continue;
        };
        let top = first
            .as_os_str()
            .to_string_lossy()
            .trim_end_matches(".rs")
            .to_string();
        if top == "lib" || top == "main" {
            continue;
        }
        let entry = imports.entry(top.clone()).or_default();
        for (line_no, code) in code_lines(path) {
            for (at, _) in code.match_indices("crate::") {
                let module: String = code[at + "crate::".len()..]
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if module != top && !module.is_empty() {
                    entry
                        .entry(module)
                        .or_insert_with(|| format!("{}:{line_no}", relative.display()));
                }
            }
        }
    }
    imports
}

/// docs/ARCHITECTURE.md's layer table, bottom first: each row's top-level modules (the
/// back-quoted names in its second column, `name/` for a folder, `name.rs` for a file).
fn layer_table() -> Vec<Vec<String>> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/ARCHITECTURE.md");
    let text = std::fs::read_to_string(path).expect("docs/ARCHITECTURE.md is readable");
    let table = text
        .split("## Layers")
        .nth(1)
        .expect("ARCHITECTURE has a \"## Layers\" section");
    let mut rows = Vec::new();
    for line in table.lines().skip_while(|line| !line.starts_with('|')) {
        if !line.starts_with('|') {
            break;
        }
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let Some(cell) = cells.get(2) else { continue };
        if cells
            .get(1)
            .is_none_or(|first| first.parse::<u32>().is_err())
        {
            continue;
        }
        let modules: Vec<String> = cell
            .split('`')
            .skip(1)
            .step_by(2)
            .map(|name| {
                name.trim_end_matches('/')
                    .trim_end_matches(".rs")
                    .to_string()
            })
            .collect();
        rows.push(modules);
    }
    rows
}

/// A newcomer finds each layer from the folder names and ARCHITECTURE's layer table, and
/// the table is the import graph: every top-level module of `src/` is in exactly one row,
/// and it imports (outside tests) only modules of the rows below its own. So the modules
/// import one another without a cycle, and each layer can be read, and changed, knowing
/// only what is below it. The web and CLI edges are the table's top row.
#[test]
fn the_layer_table_is_the_import_graph() {
    let rows = layer_table();
    assert!(rows.len() >= 8, "the layer table was not found: {rows:?}");
    let row_of = |module: &str| rows.iter().position(|row| row.iter().any(|m| m == module));
    let imports = imports_by_module();
    assert!(imports.len() > 10, "the modules were not found");
    let mut violations = Vec::new();
    for name in rows.iter().flatten() {
        if rows.iter().flatten().filter(|other| *other == name).count() > 1 {
            violations.push(format!("{name} is in more than one row"));
        }
        if !imports.contains_key(name) {
            violations.push(format!("{name} is in the table but not in src/"));
        }
    }
    for (module, imported) in &imports {
        let Some(row) = row_of(module) else {
            violations.push(format!("src/{module} is in no row of the layer table"));
            continue;
        };
        for (other, place) in imported {
            match row_of(other) {
                Some(other_row) if other_row < row => {}
                _ => violations.push(format!(
                    "{module} (row {}) imports {other} at {place}, which is not below it",
                    row + 1
                )),
            }
        }
    }
    assert!(violations.is_empty(), "{violations:#?}");
}

/// `src/` holds folders by layer and at most three loose files: `lib.rs`, `main.rs` and
/// the one pipeline every caller runs.
#[test]
fn src_holds_folders_and_three_loose_files_at_most() {
    let loose: Vec<String> = std::fs::read_dir(src())
        .expect("the source folder is readable")
        .map(|entry| entry.expect("a directory entry").path())
        .filter(|path| path.is_file())
        .map(|path| {
            path.file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    assert!(loose.len() <= 3, "{loose:?}");
    assert!(loose.iter().any(|name| name == "lib.rs"), "{loose:?}");
}
