//! The TLS material of a deployment (`companion certs`, cargo feature `zenoh`): a CA and, for
//! each host, a certificate signed by it and its private key — what the plant and the
//! controller present to each other over Zenoh's mutual TLS ([`crate::transport::zenoh_link::Security`]).
//!
//! Made with rcgen (ECDSA P-256 keys, ring underneath), no hand-written cryptography and no
//! OpenSSL. Each host's certificate carries its name as common name (what `--tls-peer`
//! expects on the other side) and as a subject alternative name, plus any address given with
//! it (`plant.local=192.168.1.20`: what the connecting side checks against the endpoint's
//! host), and may serve both ways (server and client authentication). Private keys are
//! written owner-only (`0600`), in a folder made owner-only (`0700`) if this creates it.

use std::fs::OpenOptions;
use std::io::Write;
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use rcgen::{
    BasicConstraints, CertificateParams, CertifiedIssuer, DnType, ExtendedKeyUsagePurpose, IsCa, KeyPair,
    KeyUsagePurpose,
};

/// Why the deployment's material could not be made: a bad `--hosts` list, a file in the way or
/// not writable, or rcgen refusing.
#[derive(Debug, thiserror::Error)]
pub enum CertsError {
    /// A host named `ca`, whose files would be the CA's.
    #[error("host \"ca\": the CA's own files are ca.pem and ca.key; give the host another name")]
    HostNamedCa,
    /// A host that is not `NAME` or `NAME=ADDR[+ADDR]` (as given).
    #[error("host {0:?}: expected NAME or NAME=ADDR[+ADDR], e.g. plant.local or plant.local=192.168.1.20")]
    BadHost(String),
    /// A host name given twice.
    #[error("host {0:?} given twice")]
    HostTwice(String),
    /// An empty list.
    #[error("no host: give e.g. --hosts plant.local,ctrl.local")]
    NoHost,
    /// A file of the material exists already (nothing was written).
    #[error("{} exists already: give another --out (nothing was written)", .0.display())]
    Exists(PathBuf),
    /// A file or the folder cannot be made or written: `what` was being done, naming it.
    #[error("{what}")]
    File {
        /// What was being done (`creating …`, `writing …`).
        what: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// rcgen refused a host's name or address.
    #[error("host {host:?}: {cause}")]
    HostRefused {
        /// The host's name.
        host: String,
        /// rcgen's error.
        cause: rcgen::Error,
    },
    /// rcgen failed to make a key or a certificate.
    #[error(transparent)]
    Rcgen(#[from] rcgen::Error),
}

/// `what` (made only on failure) around an I/O error.
fn file_error(what: impl FnOnce() -> String) -> impl FnOnce(std::io::Error) -> CertsError {
    move |source| CertsError::File { what: what(), source }
}

/// One host of the deployment: its name and the other addresses it is reached at.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Host {
    /// The certificate's common name and first alternative name, e.g. `plant.local`.
    pub name: String,
    /// More alternative names: IP addresses or DNS names, e.g. `192.168.1.20`.
    pub addresses: Vec<String>,
}

impl Host {
    /// Parses `NAME` or `NAME=ADDR[+ADDR…]`.
    ///
    /// # Errors
    /// [`CertsError::BadHost`]: an empty name or address, or characters outside letters,
    /// digits, `-._:`; [`CertsError::HostNamedCa`].
    pub fn parse(s: &str) -> Result<Self, CertsError> {
        let (name, rest) = s.split_once('=').map_or((s, None), |(n, r)| (n, Some(r)));
        let addresses: Vec<String> =
            rest.map(|r| r.split('+').map(str::to_string).collect()).unwrap_or_default();
        let ok =
            |x: &str| !x.is_empty() && x.bytes().all(|b| b.is_ascii_alphanumeric() || b"-._:".contains(&b));
        if name == "ca" {
            return Err(CertsError::HostNamedCa);
        }
        if !ok(name) || !addresses.iter().all(|a| ok(a)) {
            return Err(CertsError::BadHost(s.to_string()));
        }
        Ok(Self { name: name.to_string(), addresses })
    }

    /// A list `a,b=addr,…` (as `--hosts` takes it).
    ///
    /// # Errors
    /// As [`Host::parse`], an empty list ([`CertsError::NoHost`]), or a name given twice
    /// ([`CertsError::HostTwice`]).
    pub fn parse_list(s: &str) -> Result<Vec<Self>, CertsError> {
        let hosts: Vec<Self> = s.split(',').map(str::trim).map(Self::parse).collect::<Result<_, _>>()?;
        for (i, h) in hosts.iter().enumerate() {
            if hosts[..i].iter().any(|o| o.name == h.name) {
                return Err(CertsError::HostTwice(h.name.clone()));
            }
        }
        if hosts.is_empty() {
            return Err(CertsError::NoHost);
        }
        Ok(hosts)
    }
}

/// When the certificates are valid (the CA's and every host's).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Validity {
    /// Not before.
    pub start: SystemTime,
    /// Not after.
    pub end: SystemTime,
}

impl Validity {
    /// From now (less a minute, for clocks a little apart) for `days` days.
    pub fn days(days: u32) -> Self {
        let now = SystemTime::now();
        Self {
            start: now - Duration::from_secs(60),
            end: now + Duration::from_secs(u64::from(days) * 86_400),
        }
    }
}

/// The files [`make`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Material {
    /// The CA's certificate (`ca.pem`): `--tls-ca` on every host.
    pub ca: PathBuf,
    /// The CA's private key (`ca.key`): keep it off the robots, it makes new hosts.
    pub ca_key: PathBuf,
    /// Per host, in the order given: its name, certificate (`NAME.pem`) and key (`NAME.key`).
    pub hosts: Vec<(String, PathBuf, PathBuf)>,
}

fn write_new(path: &Path, text: &str, mode: u32) -> Result<(), CertsError> {
    let mut f = OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(mode)
        .open(path)
        .map_err(file_error(|| format!("creating {} (it must not exist yet)", path.display())))?;
    f.write_all(text.as_bytes()).map_err(file_error(|| format!("writing {}", path.display())))
}

/// A deployment's CA in memory: signs the hosts' certificates.
pub struct Deployment {
    issuer: CertifiedIssuer<'static, KeyPair>,
    key_pem: String,
}

impl std::fmt::Debug for Deployment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Deployment").finish_non_exhaustive()
    }
}

/// A certificate and its private key, PEM.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pem {
    /// The certificate.
    pub cert: String,
    /// The private key (PKCS#8).
    pub key: String,
}

impl Deployment {
    /// A new CA (ECDSA P-256), valid over `validity`.
    ///
    /// # Errors
    /// [`CertsError::Rcgen`]: rcgen fails.
    pub fn new(validity: Validity) -> Result<Self, CertsError> {
        let key = KeyPair::generate()?;
        let mut ca = CertificateParams::new(Vec::<String>::new())?;
        // A name of its own (from its public key): a verifier looks a certificate's issuer up
        // by name, so two deployments' CAs of one name would make "another CA" look like a
        // bad signature instead of an unknown issuer.
        let id: String = key.public_key_raw().iter().rev().take(6).map(|b| format!("{b:02x}")).collect();
        ca.distinguished_name.push(DnType::CommonName, format!("companion deployment CA {id}"));
        ca.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
        ca.key_usages =
            vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign, KeyUsagePurpose::DigitalSignature];
        ca.not_before = validity.start.into();
        ca.not_after = validity.end.into();
        let key_pem = key.serialize_pem();
        Ok(Self { issuer: CertifiedIssuer::self_signed(ca, key)?, key_pem })
    }

    /// The CA's certificate and key.
    pub fn ca(&self) -> Pem {
        Pem { cert: self.issuer.pem(), key: self.key_pem.clone() }
    }

    /// A certificate for `host` signed by this CA, valid over `validity`: its name as common
    /// name and alternative name, its addresses as more alternative names, for server and
    /// client authentication.
    ///
    /// # Errors
    /// A name or address rcgen refuses ([`CertsError::HostRefused`]), or rcgen fails
    /// ([`CertsError::Rcgen`]).
    pub fn host(&self, host: &Host, validity: Validity) -> Result<Pem, CertsError> {
        let sans: Vec<String> =
            std::iter::once(host.name.clone()).chain(host.addresses.iter().cloned()).collect();
        let mut p = CertificateParams::new(sans)
            .map_err(|cause| CertsError::HostRefused { host: host.name.clone(), cause })?;
        p.distinguished_name.push(DnType::CommonName, host.name.as_str());
        p.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        p.extended_key_usages =
            vec![ExtendedKeyUsagePurpose::ServerAuth, ExtendedKeyUsagePurpose::ClientAuth];
        p.not_before = validity.start.into();
        p.not_after = validity.end.into();
        let key = KeyPair::generate()?;
        let cert = p.signed_by(&key, &self.issuer)?;
        Ok(Pem { cert: cert.pem(), key: key.serialize_pem() })
    }
}

/// Writes `pem` as `dir/NAME.pem` and `dir/NAME.key` (the key `0600`), neither existing.
///
/// # Errors
/// [`CertsError::File`]: a file exists already, or cannot be written.
pub fn write_pair(dir: &Path, name: &str, pem: &Pem) -> Result<(PathBuf, PathBuf), CertsError> {
    let (cert, key) = (dir.join(format!("{name}.pem")), dir.join(format!("{name}.key")));
    write_new(&cert, &pem.cert, 0o644)?;
    write_new(&key, &pem.key, 0o600)?;
    Ok((cert, key))
}

/// Makes a CA and one certificate and key per host in `out` (created `0700` if missing):
/// `ca.pem`, `ca.key`, and `NAME.pem`, `NAME.key` per host.
///
/// # Errors
/// A file that exists already ([`CertsError::Exists`]: nothing is overwritten), `out` cannot
/// be made ([`CertsError::File`]), or rcgen fails.
pub fn make(out: &Path, hosts: &[Host], validity: Validity) -> Result<Material, CertsError> {
    if !out.exists() {
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(out)
            .map_err(file_error(|| format!("creating {}", out.display())))?;
    }
    let names: Vec<PathBuf> = [out.join("ca.pem"), out.join("ca.key")]
        .into_iter()
        .chain(
            hosts
                .iter()
                .flat_map(|h| [out.join(format!("{}.pem", h.name)), out.join(format!("{}.key", h.name))]),
        )
        .collect();
    if let Some(p) = names.iter().find(|p| p.exists()) {
        return Err(CertsError::Exists(p.clone()));
    }
    let ca = Deployment::new(validity)?;
    let pems: Vec<Pem> = hosts.iter().map(|h| ca.host(h, validity)).collect::<Result<_, _>>()?;
    let (ca_cert, ca_key) = write_pair(out, "ca", &ca.ca())?;
    let mut material = Material { ca: ca_cert, ca_key, hosts: Vec::new() };
    for (h, pem) in hosts.iter().zip(&pems) {
        let (cert, key) = write_pair(out, &h.name, pem)?;
        material.hosts.push((h.name.clone(), cert, key));
    }
    Ok(material)
}

#[cfg(test)]
mod tests {
    use std::os::unix::fs::PermissionsExt;

    use super::*;

    #[test]
    fn hosts_are_parsed_and_checked() {
        assert_eq!(
            Host::parse_list("plant.local=192.168.1.20+plant,ctrl").unwrap(),
            vec![
                Host { name: "plant.local".into(), addresses: vec!["192.168.1.20".into(), "plant".into()] },
                Host { name: "ctrl".into(), addresses: vec![] },
            ]
        );
        for bad in ["", "a,,b", "a=", "a/b", "a,a", "=1.2.3.4", "ca"] {
            assert!(Host::parse_list(bad).is_err(), "{bad}");
        }
        assert!(matches!(Host::parse_list("a,a"), Err(CertsError::HostTwice(h)) if h == "a"));
        assert!(matches!(Host::parse_list("ca"), Err(CertsError::HostNamedCa)));
        let e = Host::parse_list("p,a/b").unwrap_err();
        assert!(matches!(&e, CertsError::BadHost(h) if h == "a/b"), "{e}");
        assert_eq!(
            e.to_string(),
            "host \"a/b\": expected NAME or NAME=ADDR[+ADDR], e.g. plant.local or plant.local=192.168.1.20"
        );
    }

    #[test]
    fn the_material_is_written_once_with_owner_only_keys() {
        let dir = std::env::temp_dir().join(format!("companion-certs-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let m = make(&dir, &Host::parse_list("plant=127.0.0.1,ctrl").unwrap(), Validity::days(1)).unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&dir), 0o700);
        assert_eq!(mode(&m.ca_key), 0o600);
        for (_, cert, key) in &m.hosts {
            assert!(std::fs::read_to_string(cert).unwrap().starts_with("-----BEGIN CERTIFICATE-----"));
            assert!(std::fs::read_to_string(key).unwrap().contains("PRIVATE KEY"));
            assert_eq!(mode(key), 0o600);
        }
        // Nothing is overwritten.
        let e = make(&dir, &Host::parse_list("other").unwrap(), Validity::days(1)).unwrap_err();
        assert!(matches!(&e, CertsError::Exists(p) if *p == dir.join("ca.pem")), "{e}");
        assert!(e.to_string().contains("exists already"), "{e}");
        let e = write_pair(&dir, "ca", &Pem { cert: String::new(), key: String::new() }).unwrap_err();
        let CertsError::File { what, source } = &e else { panic!("not File: {e}") };
        assert_eq!(source.kind(), std::io::ErrorKind::AlreadyExists);
        assert_eq!(*what, format!("creating {} (it must not exist yet)", dir.join("ca.pem").display()));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
