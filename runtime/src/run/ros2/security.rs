//! SROS 2: whether and how the node joins the domain under DDS-Security, decided as ROS 2's
//! `rcl` decides it (`rcl/security.c`), from the environment:
//!
//! - `ROS_SECURITY_ENABLE=true` (exactly) turns security on; anything else leaves it off.
//! - `ROS_SECURITY_STRATEGY=Enforce` (exactly): the node refuses to start without valid
//!   material; anything else is permissive: without the enclave's folder or one of its files
//!   the node runs without security, and says so.
//! - `ROS_SECURITY_KEYSTORE`: the keystore; the enclave's folder is
//!   `KEYSTORE/enclaves/NAME` (`KEYSTORE/enclaves` for `/`).
//! - The enclave's name: `ROS_SECURITY_ENCLAVE_OVERRIDE` if set and not empty, else
//!   `--enclave`, else `/` (rcl's default, the root enclave).
//!
//! Whether the files are *valid* — certificates signed by the identity CA, documents signed by
//! the permissions CA, a grant naming the certificate's subject — RustDDS's builtin plugins
//! decide when the participant is made; a refusal there stops the node in either strategy, as
//! ROS 2's middlewares do.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::transport::ros2::Enclave;

/// How strictly the node holds to security.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Strategy {
    /// `ROS_SECURITY_STRATEGY=Enforce`: no valid material, no start.
    Enforce,
    /// Otherwise: without material, run without security (warned).
    Permissive,
}

/// What the environment asks for, and what the node does.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Decision {
    /// `ROS_SECURITY_ENABLE` is not `true`: a plain participant.
    Off,
    /// Secured with this enclave.
    Secure {
        /// The enclave's name and folder.
        enclave: Enclave,
        /// The strategy.
        strategy: Strategy,
    },
    /// Permissive, and the material is missing: a plain participant, and this warning.
    Unsecured {
        /// Why (one sentence).
        warning: String,
    },
}

/// What `summary.json` says of security.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct SecuritySummary {
    /// Whether the participant ran under DDS-Security.
    pub enabled: bool,
    /// The enclave's name (when enabled).
    pub enclave: Option<String>,
    /// Its folder (when enabled).
    pub directory: Option<PathBuf>,
    /// The strategy (when `ROS_SECURITY_ENABLE=true`).
    pub strategy: Option<Strategy>,
}

impl Decision {
    /// The enclave to open the participant with, if any.
    pub fn enclave(&self) -> Option<&Enclave> {
        match self {
            Self::Secure { enclave, .. } => Some(enclave),
            _ => None,
        }
    }

    /// For `summary.json`.
    pub fn summary(&self) -> SecuritySummary {
        match self {
            Self::Off => SecuritySummary { enabled: false, enclave: None, directory: None, strategy: None },
            Self::Unsecured { .. } => SecuritySummary {
                enabled: false,
                enclave: None,
                directory: None,
                strategy: Some(Strategy::Permissive),
            },
            Self::Secure { enclave, strategy } => SecuritySummary {
                enabled: true,
                enclave: Some(enclave.name.clone()),
                directory: Some(enclave.dir.clone()),
                strategy: Some(*strategy),
            },
        }
    }
}

/// Why the node refuses to start (`ROS_SECURITY_STRATEGY=Enforce` and no material, or an
/// enclave name ROS 2 does not allow).
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum SecurityError {
    /// `Enforce`, and the material is missing.
    #[error(
        "SROS 2: ROS_SECURITY_ENABLE=true and ROS_SECURITY_STRATEGY=Enforce, but {0}: the node does not start \
         without its security files"
    )]
    Missing(String),
    /// Not a ROS name.
    #[error("--enclave {0:?} is not a ROS 2 enclave name (absolute, such as /companion or /robot/driver)")]
    Name(String),
}

/// Whether `name` is an enclave name as rcl accepts it: absolute, its parts letters, digits
/// and `_`, none starting with a digit (a ROS namespace).
pub fn valid_name(name: &str) -> bool {
    name == "/"
        || name.strip_prefix('/').is_some_and(|rest| {
            rest.split('/').all(|p| {
                !p.is_empty()
                    && !p.starts_with(|c: char| c.is_ascii_digit())
                    && p.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            })
        })
}

/// The enclave's folder in `keystore` (rcl's exact match: `enclaves/` and the name's parts).
pub fn enclave_dir(keystore: &Path, name: &str) -> PathBuf {
    let mut d = keystore.join("enclaves");
    for part in name.split('/').filter(|p| !p.is_empty()) {
        d.push(part);
    }
    d
}

/// Decides from the environment (`env`: a variable's value, `None` if unset) and `--enclave`.
///
/// # Errors
/// `Enforce` and no keystore, folder or file; an enclave name that is not a ROS name.
pub fn decide(
    enclave_flag: Option<&str>,
    env: &dyn Fn(&str) -> Option<String>,
) -> Result<Decision, SecurityError> {
    let name = match env("ROS_SECURITY_ENCLAVE_OVERRIDE").filter(|v| !v.is_empty()) {
        Some(v) => v,
        None => enclave_flag.unwrap_or("/").to_string(),
    };
    if !valid_name(&name) {
        return Err(SecurityError::Name(name));
    }
    if env("ROS_SECURITY_ENABLE").as_deref() != Some("true") {
        return Ok(Decision::Off);
    }
    let strategy = if env("ROS_SECURITY_STRATEGY").as_deref() == Some("Enforce") {
        Strategy::Enforce
    } else {
        Strategy::Permissive
    };
    // What is missing, said once for either strategy.
    let refuse = |lack: String| {
        match strategy {
        Strategy::Enforce => Err(SecurityError::Missing(lack)),
        Strategy::Permissive => Ok(Decision::Unsecured {
            warning: format!(
                "SROS 2: ROS_SECURITY_ENABLE=true, but {lack}; ROS_SECURITY_STRATEGY is not Enforce, so the node \
                 runs WITHOUT security"
            ),
        }),
    }
    };
    let Some(keystore) = env("ROS_SECURITY_KEYSTORE").filter(|v| !v.is_empty()) else {
        return refuse("ROS_SECURITY_KEYSTORE is not set".into());
    };
    let make = format!("(scripts/sros2-keystore enclave KEYSTORE {name} makes it)");
    let dir = enclave_dir(Path::new(&keystore), &name);
    if !dir.is_dir() {
        return refuse(format!("enclave {name} has no folder {} {make}", dir.display()));
    }
    let enclave = Enclave { name, dir };
    let missing = enclave.missing();
    if !missing.is_empty() {
        return refuse(format!(
            "enclave {} has no {} in {} {make}",
            enclave.name,
            missing.join(", "),
            enclave.dir.display()
        ));
    }
    Ok(Decision::Secure { enclave, strategy })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env_of<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| vars.iter().find(|(n, _)| *n == k).map(|(_, v)| (*v).to_string())
    }

    /// A keystore folder with enclave `/a/b` holding every file but `permissions.p7s`.
    fn keystore(tag: &str) -> PathBuf {
        let ks = std::env::temp_dir().join(format!("companion-sros2-{tag}-{}", std::process::id()));
        let d = enclave_dir(&ks, "/a/b");
        std::fs::create_dir_all(&d).unwrap();
        for f in &Enclave::FILES[..5] {
            std::fs::write(d.join(f), "x").unwrap();
        }
        ks
    }

    #[test]
    fn security_is_on_only_for_exactly_true_and_enforce_only_for_exactly_enforce() {
        for v in ["1", "True", "yes", ""] {
            assert_eq!(decide(None, &env_of(&[("ROS_SECURITY_ENABLE", v)])), Ok(Decision::Off), "{v}");
        }
        // rcl compares with strcmp: "enforce" is permissive.
        let d =
            decide(None, &env_of(&[("ROS_SECURITY_ENABLE", "true"), ("ROS_SECURITY_STRATEGY", "enforce")]))
                .unwrap();
        assert!(matches!(d, Decision::Unsecured { .. }), "{d:?}");
        let e =
            decide(None, &env_of(&[("ROS_SECURITY_ENABLE", "true"), ("ROS_SECURITY_STRATEGY", "Enforce")]));
        assert_eq!(e, Err(SecurityError::Missing("ROS_SECURITY_KEYSTORE is not set".into())));
    }

    #[test]
    fn the_enclave_folder_follows_rcl_and_the_override_wins() {
        let ks = keystore("dir");
        assert_eq!(enclave_dir(&ks, "/"), ks.join("enclaves"));
        assert_eq!(enclave_dir(&ks, "/a/b"), ks.join("enclaves").join("a").join("b"));
        std::fs::write(enclave_dir(&ks, "/a/b").join("permissions.p7s"), "x").unwrap();
        let k = ks.to_str().unwrap();
        let base = [
            ("ROS_SECURITY_ENABLE", "true"),
            ("ROS_SECURITY_STRATEGY", "Enforce"),
            ("ROS_SECURITY_KEYSTORE", k),
        ];
        let d = decide(Some("/a/b"), &env_of(&base)).unwrap();
        assert_eq!(d.enclave().unwrap().dir, ks.join("enclaves/a/b"));
        assert_eq!(d.summary().strategy, Some(Strategy::Enforce));
        let mut over = base.to_vec();
        over.push(("ROS_SECURITY_ENCLAVE_OVERRIDE", "/a/b"));
        assert_eq!(decide(Some("/elsewhere"), &env_of(&over)).unwrap(), d);
        let e = decide(Some("/elsewhere"), &env_of(&base)).unwrap_err().to_string();
        assert!(e.contains("enclave /elsewhere has no folder") && e.contains("enclaves/elsewhere"), "{e}");
        std::fs::remove_dir_all(&ks).unwrap();
    }

    #[test]
    fn a_missing_file_is_named_under_enforce_and_warned_of_otherwise() {
        let ks = keystore("files");
        let k = ks.to_str().unwrap();
        let e = decide(
            Some("/a/b"),
            &env_of(&[
                ("ROS_SECURITY_ENABLE", "true"),
                ("ROS_SECURITY_STRATEGY", "Enforce"),
                ("ROS_SECURITY_KEYSTORE", k),
            ]),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with(
                "SROS 2: ROS_SECURITY_ENABLE=true and ROS_SECURITY_STRATEGY=Enforce, but enclave /a/b has no permissions.p7s in "
            ),
            "{e}"
        );
        let d =
            decide(Some("/a/b"), &env_of(&[("ROS_SECURITY_ENABLE", "true"), ("ROS_SECURITY_KEYSTORE", k)]))
                .unwrap();
        match d {
            Decision::Unsecured { warning } => {
                assert!(
                    warning.contains("no permissions.p7s") && warning.ends_with("WITHOUT security"),
                    "{warning}"
                );
            }
            other => panic!("{other:?}"),
        }
        std::fs::remove_dir_all(&ks).unwrap();
    }

    #[test]
    fn enclave_names_are_ros_names() {
        for ok in ["/", "/companion", "/robot/driver_1"] {
            assert!(valid_name(ok), "{ok}");
        }
        for bad in ["", "companion", "/a//b", "/1a", "/a-b", "/a/", "/a b"] {
            assert!(!valid_name(bad), "{bad}");
            assert_eq!(decide(Some(bad), &env_of(&[])), Err(SecurityError::Name(bad.to_string())));
        }
    }
}
