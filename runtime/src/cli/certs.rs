//! `companion certs`: the TLS material of a two-host (or larger) deployment.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

/// Flags of `companion certs`.
#[derive(Args, Clone, Debug)]
pub struct CertsArgs {
    /// The folder to write into (nothing in it is overwritten).
    ///
    /// The folder to write into (made owner-only if missing; no file in it is overwritten).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// The hosts: NAME or NAME=ADDR[+ADDR], comma-separated.
    ///
    /// The hosts, comma-separated: each NAME (the certificate's name, what the peer's
    /// --tls-peer expects) or NAME=ADDR[+ADDR] (more addresses it is reached at, e.g.
    /// plant.local=192.168.1.20: the controller's --connect host must be one of them).
    #[arg(long, value_name = "NAME[=ADDR],…")]
    pub hosts: String,
    /// How long the certificates are valid, in days.
    ///
    /// How long the certificates are valid, in days (1–36500).
    #[arg(long, default_value_t = 365, value_parser = clap::value_parser!(u32).range(1..=36_500))]
    pub days: u32,
}

/// Makes the CA and the hosts' certificates and says which file goes where.
///
/// # Errors
/// A bad host list, a file that exists, or a build without the Zenoh transport.
pub fn run(a: &CertsArgs) -> Result<()> {
    #[cfg(feature = "zenoh")]
    {
        use companion_runtime::transport::certs::{make, Host, Validity};
        let hosts = Host::parse_list(&a.hosts)?;
        let m = make(&a.out, &hosts, Validity::days(a.days))?;
        println!("wrote {} (the CA: copy it to every host)", m.ca.display());
        println!(
            "wrote {} (the CA's key, 0600: keep it off the robots; it signs new hosts)",
            m.ca_key.display()
        );
        for (name, cert, key) in &m.hosts {
            println!("wrote {} and {} (0600): for host {name} only", cert.display(), key.display());
        }
        if let [(p, pc, pk), (c, cc, ck), ..] = &m.hosts[..] {
            let ca = m.ca.display();
            println!("\non {p}:  companion plant --transport zenoh --listen quic/0.0.0.0:7447 \\");
            println!(
                "    --tls-ca {ca} --tls-cert {} --tls-key {} --tls-peer {c}",
                pc.display(),
                pk.display()
            );
            println!("on {c}:  companion control --transport zenoh --connect quic/{p}:7447 \\");
            println!(
                "    --tls-ca {ca} --tls-cert {} --tls-key {} --tls-peer {p}",
                cc.display(),
                ck.display()
            );
        }
        Ok(())
    }
    #[cfg(not(feature = "zenoh"))]
    {
        let _ = a;
        anyhow::bail!("companion certs: {}", companion_runtime::transport::BUILD_WITH_ZENOH)
    }
}
