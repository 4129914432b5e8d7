//! Checks of a secured router's and clients' files before Zenoh sees them,
//! so that a broken file is a clear message naming the file and the field
//! (exit code 2) rather than a router that refuses everyone, or Zenoh's
//! "Access control not enabled" at start-up.

use std::collections::HashSet;
use std::path::Path;

use serde_json::Value;

use super::SecureError;

/// One setting of a Zenoh configuration as JSON (`null` when unset).
fn setting(config: &zenoh::Config, key: &str) -> Value {
    config
        .get_json(key)
        .ok()
        .and_then(|text| serde_json::from_str(&text).ok())
        .unwrap_or(Value::Null)
}

/// Checks the router configuration loaded from `file`: its user/password
/// dictionary and the cross-references of its `access_control`.
pub fn router(file: &Path, config: &zenoh::Config) -> Result<(), SecureError> {
    let field = |field: &str, problem: String| SecureError::Field {
        file: file.to_path_buf(),
        field: field.to_string(),
        problem,
    };
    let dictionary = setting(config, "transport/auth/usrpwd/dictionary_file");
    let users = match &dictionary {
        Value::String(path) => Some(dictionary_users(Path::new(path))?),
        Value::Null => None,
        other => {
            return Err(field(
                "transport.auth.usrpwd.dictionary_file",
                format!("expected a file name, found {other}"),
            ));
        }
    };
    let acl = setting(config, "access_control");
    if acl.get("enabled") != Some(&Value::Bool(true)) {
        return Ok(());
    }
    let ids = |section: &str| -> Result<HashSet<String>, SecureError> {
        let mut seen = HashSet::new();
        for (i, entry) in acl[section].as_array().into_iter().flatten().enumerate() {
            let id = entry["id"].as_str().unwrap_or_default().to_string();
            if !seen.insert(id.clone()) {
                return Err(field(
                    &format!("access_control.{section}[{i}].id"),
                    format!("duplicate id {id:?}"),
                ));
            }
        }
        Ok(seen)
    };
    let rules = ids("rules")?;
    let subjects = ids("subjects")?;
    let mtls = setting(config, "transport/link/tls/enable_mtls") == Value::Bool(true);
    for (i, subject) in acl["subjects"].as_array().into_iter().flatten().enumerate() {
        let common_names = subject["cert_common_names"].as_array();
        if common_names.is_some_and(|n| !n.is_empty()) && !mtls {
            return Err(field(
                &format!("access_control.subjects[{i}].cert_common_names"),
                "subjects by certificate need transport.link.tls.enable_mtls: true: \
                 without client certificates every client is denied"
                    .into(),
            ));
        }
        let names = subject["usernames"].as_array();
        if names.is_some_and(|n| !n.is_empty()) && users.is_none() {
            return Err(field(
                &format!("access_control.subjects[{i}].usernames"),
                "subjects by user name need transport.auth.usrpwd.dictionary_file: \
                 without it nobody authenticates and every client is denied"
                    .into(),
            ));
        }
    }
    for (i, policy) in acl["policies"].as_array().into_iter().flatten().enumerate() {
        for (section, known) in [("rules", &rules), ("subjects", &subjects)] {
            for (j, id) in policy[section].as_array().into_iter().flatten().enumerate() {
                let id = id.as_str().unwrap_or_default();
                if !known.contains(id) {
                    return Err(field(
                        &format!("access_control.policies[{i}].{section}[{j}]"),
                        format!("no {} has the id {id:?}", &section[..section.len() - 1]),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The user names of a user/password dictionary (`<user>:<password>` per
/// line, blank lines allowed), each line checked as Zenoh reads it.
pub fn dictionary_users(file: &Path) -> Result<HashSet<String>, SecureError> {
    Ok(dictionary(file)?
        .into_iter()
        .map(|(user, _)| user)
        .collect())
}

/// The (user, password) pairs of a user/password dictionary, each line
/// checked as Zenoh reads it.
pub fn dictionary(file: &Path) -> Result<Vec<(String, String)>, SecureError> {
    // A dictionary holds a line per node: a site of thousands is well
    // under this; a path to anything endless is refused, not read.
    const MAX_DICTIONARY_BYTES: u64 = 16 << 20;
    let text = ickon_proto::text_file::read_bounded(file, MAX_DICTIONARY_BYTES)
        .map_err(|reason| SecureError::io(file, std::io::Error::other(reason)))?;
    let mut users = HashSet::new();
    let mut entries = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line_error = |problem: &str| SecureError::Line {
            file: file.to_path_buf(),
            line: n + 1,
            problem: problem.to_string(),
        };
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let (user, password) = line
            .split_once(':')
            .ok_or_else(|| line_error("expected <user>:<password>"))?;
        if user.trim().is_empty() {
            return Err(line_error("empty user name"));
        }
        if password.trim().is_empty() {
            return Err(line_error("empty password"));
        }
        if !users.insert(user.trim().to_string()) {
            return Err(line_error(
                "user listed twice (the last password would win)",
            ));
        }
        entries.push((user.trim().to_string(), password.trim().to_string()));
    }
    if users.is_empty() {
        return Err(SecureError::Line {
            file: file.to_path_buf(),
            line: 1,
            problem: "no user: nobody could connect".into(),
        });
    }
    Ok(entries)
}

/// Loads a client configuration and checks that it carries a credential:
/// the user name it authenticates as.
pub fn client(file: &Path) -> Result<String, SecureError> {
    let config = zenoh::Config::from_file(file).map_err(|e| SecureError::Field {
        file: file.to_path_buf(),
        field: "(file)".into(),
        problem: e.to_string(),
    })?;
    let field = |name: &str| match setting(&config, &format!("transport/auth/usrpwd/{name}")) {
        Value::String(s) if !s.is_empty() => Ok(s),
        _ => Err(SecureError::Field {
            file: file.to_path_buf(),
            field: format!("transport.auth.usrpwd.{name}"),
            problem: "missing: a client of a secured router needs a user and a password".into(),
        }),
    };
    let user = field("user")?;
    field("password")?;
    Ok(user)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn a_broken_dictionary_names_the_file_and_line() {
        let tmp = tempfile::tempdir().unwrap();
        for (text, expect) in [
            ("a:1\nb\n", ":2: expected <user>:<password>"),
            ("a:1\n:x\n", ":2: empty user name"),
            ("a:\n", ":1: empty password"),
            ("a:1\na:2\n", ":2: user listed twice"),
            ("\n\n", ":1: no user"),
        ] {
            let f = write(tmp.path(), "users.txt", text);
            let err = dictionary_users(&f).unwrap_err().to_string();
            assert!(
                err.contains("users.txt") && err.contains(expect),
                "{text:?}: {err}"
            );
        }
        let f = write(tmp.path(), "users.txt", "a:1\n\n b : 2 \n");
        assert_eq!(dictionary_users(&f).unwrap().len(), 2);
    }

    fn router_text(users: &Path, policy_rule: &str) -> String {
        format!(
            r#"{{ mode: "router",
              transport: {{ auth: {{ usrpwd: {{ dictionary_file: "{}" }} }} }},
              access_control: {{ enabled: true, default_permission: "deny",
                rules: [{{ id: "r", messages: ["put"], flows: ["ingress"], permission: "allow", key_exprs: ["a/**"] }}],
                subjects: [{{ id: "s", usernames: ["u"] }}],
                policies: [{{ rules: ["{policy_rule}"], subjects: ["s"] }}] }} }}"#,
            users.display()
        )
    }

    #[test]
    fn an_acl_policy_naming_an_unknown_rule_is_refused_with_its_field() {
        let tmp = tempfile::tempdir().unwrap();
        let users = write(tmp.path(), "users.txt", "u:pw\n");
        let good = write(tmp.path(), "good.json5", &router_text(&users, "r"));
        let config = zenoh::Config::from_file(&good).unwrap();
        router(&good, &config).unwrap();
        let bad = write(tmp.path(), "bad.json5", &router_text(&users, "nope"));
        let config = zenoh::Config::from_file(&bad).unwrap();
        let err = router(&bad, &config).unwrap_err().to_string();
        assert!(
            err.contains("bad.json5") && err.contains("access_control.policies[0].rules[0]"),
            "{err}"
        );
    }

    #[test]
    fn subjects_by_certificate_need_client_certificates() {
        let tmp = tempfile::tempdir().unwrap();
        let users = write(tmp.path(), "users.txt", "u:pw\n");
        let text = router_text(&users, "r").replace(
            r#"usernames: ["u"]"#,
            r#"usernames: ["u"], cert_common_names: ["u"]"#,
        );
        let bad = write(tmp.path(), "bad.json5", &text);
        let config = zenoh::Config::from_file(&bad).unwrap();
        let err = router(&bad, &config).unwrap_err().to_string();
        assert!(
            err.contains("subjects[0].cert_common_names") && err.contains("enable_mtls"),
            "{err}"
        );
    }

    #[test]
    fn zenoh_itself_refuses_a_misspelt_acl_field() {
        let tmp = tempfile::tempdir().unwrap();
        let users = write(tmp.path(), "users.txt", "u:pw\n");
        let text = router_text(&users, "r").replace("key_exprs", "keys");
        let bad = write(tmp.path(), "bad.json5", &text);
        let err = zenoh::Config::from_file(&bad).unwrap_err().to_string();
        assert!(err.contains("keys") || err.contains("key_exprs"), "{err}");
    }

    #[test]
    fn a_client_without_a_password_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let f = write(
            tmp.path(),
            "c.json5",
            r#"{ mode: "client", transport: { auth: { usrpwd: { user: "robot-r1" } } } }"#,
        );
        let err = client(&f).unwrap_err().to_string();
        assert!(err.contains("c.json5") && err.contains("password"), "{err}");
        let f = write(
            tmp.path(),
            "d.json5",
            r#"{ mode: "client", transport: { auth: { usrpwd: { user: "robot-r1", password: "x" } } } }"#,
        );
        assert_eq!(client(&f).unwrap(), "robot-r1");
    }
}
