//! Two network namespaces joined by a veth pair, for running the plant and the controller on
//! "two machines" (`ip netns`, as root). Removed when dropped — also when a test fails —
//! which takes the veth pair with them.

use std::process::Command;

/// Two namespaces, `A` at `10.R.S.1/24` and `B` at `10.R.S.2/24`, joined by a veth pair.
pub struct NetnsPair {
    /// The first namespace's name.
    pub a: String,
    /// The second namespace's name.
    pub b: String,
    /// The first one's address.
    pub addr_a: String,
    /// The second one's address.
    pub addr_b: String,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let o = Command::new("ip").args(args).output().map_err(|e| format!("ip {}: {e}", args.join(" ")))?;
    if o.status.success() {
        Ok(())
    } else {
        Err(format!("ip {}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr).trim()))
    }
}

impl NetnsPair {
    /// Sets them up (names unique to this process and `tag`), or says why it cannot.
    ///
    /// # Errors
    /// `ip` is missing, or namespaces are not permitted (not root, no `CAP_SYS_ADMIN`).
    pub fn create(tag: u8) -> Result<Self, String> {
        let pid = std::process::id();
        let (a, b) = (format!("cz{tag}a{pid}"), format!("cz{tag}b{pid}"));
        let (va, vb) = (format!("vz{tag}a{pid}"), format!("vz{tag}b{pid}"));
        // A /24 of 10.0.0.0/8 from the pid and the tag, unlikely to collide with the machine's.
        let net = format!("10.{}.{}", 200 + (pid % 50), (pid / 50 % 200) as u8 ^ tag);
        let pair = Self { a, b, addr_a: format!("{net}.1"), addr_b: format!("{net}.2") };
        // From here on, Drop removes whatever was made.
        ip(&["netns", "add", &pair.a])?;
        ip(&["netns", "add", &pair.b])?;
        let steps: [&[&str]; 8] = [
            &["link", "add", &va, "netns", &pair.a, "type", "veth", "peer", "name", &vb, "netns", &pair.b],
            &["-n", &pair.a, "addr", "add", &format!("{}/24", pair.addr_a), "dev", &va],
            &["-n", &pair.b, "addr", "add", &format!("{}/24", pair.addr_b), "dev", &vb],
            &["-n", &pair.a, "link", "set", &va, "up"],
            &["-n", &pair.b, "link", "set", &vb, "up"],
            &["-n", &pair.a, "link", "set", "lo", "up"],
            &["-n", &pair.b, "link", "set", "lo", "up"],
            &["-n", &pair.a, "link", "show", &va],
        ];
        for s in steps {
            ip(s)?;
        }
        Ok(pair)
    }

    /// Takes the link between them down in namespace A (a silent network: no packet passes,
    /// no connection is closed).
    pub fn link_down(&self) -> Result<(), String> {
        let va = self.a.replacen("cz", "vz", 1);
        ip(&["-n", &self.a, "link", "set", &va, "down"])
    }
}

impl Drop for NetnsPair {
    fn drop(&mut self) {
        for ns in [&self.a, &self.b] {
            let _ = ip(&["netns", "del", ns]);
        }
    }
}
