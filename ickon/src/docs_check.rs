//! The documentation cannot drift from the code: the CLI reference
//! (`docs/cli.md`) is generated from the clap definitions, every command
//! line shown in README.md and docs/ parses with them, every relative
//! link and repository path they name exists, and every key of the
//! shipped sites, MSU configuration and noise profiles is in the
//! configuration reference.
//!
//! `ICKON_WRITE_CLI_REFERENCE=1 cargo test -p ickon docs_check` writes the
//! reference anew after a change to the command line.

use std::path::{Path, PathBuf};

use clap::{CommandFactory, Parser};

use ickon::cli::Cli;

/// The repository's root (the binary crate sits one level below it).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// README.md and every Markdown file under docs/.
fn documents() -> Vec<PathBuf> {
    let mut out = vec![root().join("README.md")];
    let mut dirs = vec![root().join("docs")];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir)
            .expect("docs/ is readable")
            .flatten()
        {
            let path = entry.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// The CLI reference as the code defines it: `ickon`, then each node's
/// own binary (`ickon-central`, `ickon-cell`, `ickon-msu`, `ickon-world`,
/// the same flags as the hidden `ickon node <role>`).
fn cli_reference() -> String {
    let options = |title: &str| {
        clap_markdown::MarkdownOptions::new()
            .title(title.to_string())
            .show_footer(false)
            .show_table_of_contents(false)
    };
    let cli = Cli::command();
    let mut out = clap_markdown::help_markdown_command_custom(
        &cli,
        &options("`ickon` command-line reference").show_table_of_contents(true),
    );
    let node = cli.find_subcommand("node").expect("`ickon node` exists");
    let binaries = [
        ("central", "ickon-central"),
        ("cell", "ickon-cell"),
        ("msu", "ickon-msu"),
        ("world", "ickon-world"),
    ];
    for (role, name) in binaries {
        let binary = node
            .find_subcommand(role)
            .expect("every node role exists")
            .clone()
            .name(name)
            .bin_name(name);
        out.push('\n');
        out.push_str(&clap_markdown::help_markdown_command_custom(
            &binary,
            &options(&format!("`{name}` command-line reference")),
        ));
    }
    out
}

#[test]
fn the_cli_reference_is_the_one_the_code_generates() {
    let path = root().join("docs/cli.md");
    let generated = cli_reference();
    if std::env::var_os("ICKON_WRITE_CLI_REFERENCE").is_some() {
        std::fs::write(&path, &generated).expect("docs/cli.md is writable");
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "docs/cli.md differs from what the command-line definitions generate: \
         run `ICKON_WRITE_CLI_REFERENCE=1 cargo test -p ickon docs_check` and commit it"
    );
}

/// The command lines of the shell blocks of `text` (continuation lines
/// joined, comments cut), with their line numbers.
fn command_lines(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut in_block = false;
    let mut shell = false;
    let mut pending: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if let Some(lang) = trimmed.strip_prefix("```") {
            in_block = !in_block;
            shell = in_block
                && !matches!(
                    lang.trim(),
                    "text" | "mermaid" | "ini" | "toml" | "json" | "json5"
                );
            continue;
        }
        if !(in_block && shell) {
            continue;
        }
        let (start, mut joined) = match pending.take() {
            Some((n, so_far)) => (n, so_far + " " + trimmed),
            None => {
                let cmd = without_sudo(trimmed.strip_prefix("$ ").unwrap_or(trimmed));
                if !(cmd.starts_with("ickon ")
                    || cmd.starts_with("ickon-")
                    || cmd == "ickon"
                    || cmd.starts_with("cargo run"))
                {
                    continue;
                }
                (i + 1, cmd.to_string())
            }
        };
        if let Some(rest) = joined.strip_suffix('\\') {
            pending = Some((start, rest.trim_end().to_string()));
            continue;
        }
        if let Some(cut) = joined.find(" #") {
            joined.truncate(cut);
        }
        out.push((start, joined.trim().to_string()));
    }
    out
}

/// `cmd` without a leading `sudo` or `sudo -u USER`: the command it runs
/// is checked as any other.
fn without_sudo(cmd: &str) -> &str {
    let Some(rest) = cmd.strip_prefix("sudo ") else {
        return cmd;
    };
    let rest = rest.trim_start();
    match rest.strip_prefix("-u ") {
        Some(user_and_cmd) => user_and_cmd
            .trim_start()
            .split_once(' ')
            .map_or("", |(_, c)| c.trim_start()),
        None => rest,
    }
}

/// `line` as the `ickon` binary's arguments (a node binary's as `ickon node
/// <role>`; `cargo run ... -- ARGS` as `ickon ARGS`), or `None` if it is not
/// an ICKON-rs command.
fn as_ickon_args(line: &str) -> Option<Vec<String>> {
    let words = shlex::split(line)?;
    // Placeholders the docs use for numbers; the command ends where the
    // shell's next one begins (`ickon ... || echo ...`).
    let words: Vec<String> = words
        .into_iter()
        .take_while(|w| !matches!(w.as_str(), "||" | "&&" | "|" | ";"))
        .map(|w| if w == "N" { "1".to_string() } else { w })
        .collect();
    let (first, rest) = words.split_first()?;
    let mut args = vec!["ickon".to_string()];
    match first.as_str() {
        "ickon" => {}
        "cargo" => {
            let dashes = rest.iter().position(|w| w == "--")?;
            if !rest[..dashes].iter().any(|w| w == "ickon") {
                return None;
            }
            args.extend(rest[dashes + 1..].iter().cloned());
            return Some(args);
        }
        node => {
            let role = node.strip_prefix("ickon-")?;
            args.extend(["node".to_string(), role.to_string()]);
        }
    }
    args.extend(rest.iter().cloned());
    Some(args)
}

#[test]
fn every_command_line_in_the_docs_parses() {
    let mut problems = Vec::new();
    let mut checked = 0;
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).expect("readable");
        for (line, command) in command_lines(&text) {
            let Some(args) = as_ickon_args(&command) else {
                continue;
            };
            checked += 1;
            if let Err(e) = Cli::try_parse_from(&args) {
                use clap::error::ErrorKind::{DisplayHelp, DisplayVersion};
                if !matches!(e.kind(), DisplayHelp | DisplayVersion) {
                    let first = e.to_string().lines().next().unwrap_or_default().to_string();
                    problems.push(format!("{}:{line}: {command}: {first}", doc.display()));
                }
            }
        }
    }
    assert!(
        checked >= 20,
        "only {checked} command lines found in the docs"
    );
    assert!(
        problems.is_empty(),
        "command lines that do not parse:\n{}",
        problems.join("\n")
    );
}

/// The folders at the repository's root: a path in backticks that starts
/// with one of them names a file of the repository.
fn top_level_folders() -> Vec<String> {
    std::fs::read_dir(root())
        .expect("the root is readable")
        .flatten()
        .filter(|e| e.path().is_dir())
        .filter_map(|e| e.file_name().to_str().map(str::to_string))
        .filter(|n| !n.starts_with('.') && n != "target")
        .collect()
}

#[test]
fn every_relative_link_and_named_path_exists() {
    let folders = top_level_folders();
    let mut problems = Vec::new();
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).expect("readable");
        let dir = doc.parent().expect("a document is in a folder");
        for (n, line) in text.lines().enumerate() {
            for target in links(line) {
                let target = target.split('#').next().unwrap_or_default();
                if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
                    continue;
                }
                if !dir.join(target).exists() {
                    problems.push(format!("{}:{}: link {target}", doc.display(), n + 1));
                }
            }
            for path in code_spans(line) {
                let first = path.split('/').next().unwrap_or_default();
                // A file (with an extension) or a folder (with a final
                // slash) under a folder of the repository; `sim/probe` is
                // a key, not a path.
                let last = path
                    .trim_end_matches('/')
                    .rsplit('/')
                    .next()
                    .unwrap_or_default();
                let named = path.contains('/')
                    && folders.iter().any(|f| f == first)
                    && (path.ends_with('/') || last.contains('.'))
                    && !path.contains(['*', '<', '{', ' ', '$']);
                if named && !root().join(path).exists() {
                    problems.push(format!("{}:{}: path {path}", doc.display(), n + 1));
                }
            }
        }
    }
    assert!(
        problems.is_empty(),
        "missing files:\n{}",
        problems.join("\n")
    );
}

/// The targets of the Markdown links `[text](target)` of a line.
fn links(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find("](") {
        let after = &rest[i + 2..];
        let Some(end) = after.find(')') else { break };
        out.push(after[..end].trim());
        rest = &after[end..];
    }
    out
}

/// The contents of the code spans `` `...` `` of a line.
fn code_spans(line: &str) -> Vec<&str> {
    line.split('`').skip(1).step_by(2).collect()
}

#[test]
fn the_checks_find_what_they_look_for() {
    let text = "x\n```sh\nickon sim --robots 2 \\\n  --duration 5   # short\nls\n```\n```text\nickon nonsense\n```\n";
    assert_eq!(
        command_lines(text),
        vec![(3, "ickon sim --robots 2 --duration 5".to_string())]
    );
    assert_eq!(
        as_ickon_args("ickon-cell --cell c1"),
        Some(vec![
            "ickon".into(),
            "node".into(),
            "cell".into(),
            "--cell".into(),
            "c1".into()
        ])
    );
    assert_eq!(
        as_ickon_args("cargo run --release -p ickon -- sim"),
        Some(vec!["ickon".into(), "sim".into()])
    );
    assert!(Cli::try_parse_from(as_ickon_args("ickon sim --robots two").unwrap()).is_err());
    assert_eq!(
        links("see [a](docs/x.md#y) and [b](https://e.org)"),
        vec!["docs/x.md#y", "https://e.org"]
    );
    assert_eq!(
        code_spans("a `deploy/sites/lab.toml` b `x`"),
        vec!["deploy/sites/lab.toml", "x"]
    );
}

/// The keys docs/configuration.md documents: the first cell of its tables
/// and the tables named in its headings (`[filter.params]`, `[[cells]]`).
fn documented_keys() -> std::collections::HashSet<String> {
    let text = std::fs::read_to_string(root().join("docs/configuration.md")).expect("readable");
    let mut keys = std::collections::HashSet::new();
    for line in text.lines() {
        if let Some(cell) = line.strip_prefix("| `") {
            keys.extend(cell.split('`').next().map(str::to_string));
        } else if line.starts_with('#') {
            for span in code_spans(line) {
                keys.insert(span.trim_matches(['[', ']']).to_string());
            }
        }
    }
    keys
}

/// Every key of `table` as a dotted path (a key of an array of tables
/// under the array's name), tables by their keys alone.
fn dotted_keys(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
    for (key, value) in table {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match value {
            // A table is documented by its keys.
            toml::Value::Table(inner) => {
                dotted_keys(inner, &path, out);
                continue;
            }
            toml::Value::Array(items) => {
                for item in items {
                    if let toml::Value::Table(inner) = item {
                        dotted_keys(inner, &path, out);
                    }
                }
            }
            _ => {}
        }
        out.push(path);
    }
}

#[test]
fn every_key_of_the_shipped_files_is_in_the_configuration_reference() {
    let documented = documented_keys();
    let mut files = vec![
        root().join("deploy/sites/lab.toml"),
        root().join("deploy/sites/warehouse.toml"),
        root().join("deploy/msu.toml"),
    ];
    for entry in std::fs::read_dir(root().join("deploy/profiles"))
        .expect("profiles")
        .flatten()
    {
        files.extend(Some(entry.path()).filter(|p| p.extension().is_some_and(|e| e == "toml")));
    }
    let mut missing = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).expect("readable");
        let table: toml::Table = text.parse().expect("a shipped file parses");
        let mut keys = Vec::new();
        dotted_keys(&table, "", &mut keys);
        for key in keys {
            // Documented under its table: any tail of the dotted path.
            let parts: Vec<&str> = key.split('.').collect();
            let known = (0..parts.len()).any(|k| documented.contains(&parts[k..].join(".")));
            if !known {
                missing.push(format!("{}: {key}", file.display()));
            }
        }
    }
    missing.sort();
    missing.dedup();
    assert!(
        missing.is_empty(),
        "keys of shipped files that docs/configuration.md does not document:\n{}",
        missing.join("\n")
    );
}

#[test]
fn a_command_run_with_sudo_is_checked_as_the_command() {
    assert_eq!(
        without_sudo("sudo ickon site check x"),
        "ickon site check x"
    );
    assert_eq!(
        without_sudo("sudo -u ickon ickon admin status"),
        "ickon admin status"
    );
    assert_eq!(
        without_sudo("sudo install -m 0755 a b"),
        "install -m 0755 a b"
    );
    assert_eq!(without_sudo("ickon admin"), "ickon admin");
    assert_eq!(
        as_ickon_args("ickon admin status || echo refused"),
        Some(vec!["ickon".into(), "admin".into(), "status".into()])
    );
    let lines =
        command_lines("```sh\nsudo -u ickon ickon admin status \\\n    --site-name hall\n```\n");
    assert_eq!(
        lines,
        vec![(2, "ickon admin status --site-name hall".to_string())]
    );
}
