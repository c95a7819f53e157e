//! A TCP forwarding proxy for fault tests: every byte is forwarded after a fixed delay in
//! each direction; on command it stalls (forwards nothing, keeps the connections: a silent
//! network) or cuts (closes every connection and refuses new ones: a partition the kernel
//! reports). Stopped and its threads ended when dropped.

use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::mpsc::{channel, Receiver};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

const FORWARD: u8 = 0;
const STALL: u8 = 1;
const CUT: u8 = 2;

#[derive(Default)]
struct State {
    mode: AtomicU8,
    stop: AtomicBool,
    streams: Mutex<Vec<TcpStream>>,
}

impl State {
    fn close_all(&self) {
        for s in self.streams.lock().unwrap().drain(..) {
            let _ = s.shutdown(Shutdown::Both);
        }
    }
}

/// The proxy: listens on `127.0.0.1:port`, forwards to the upstream address.
pub struct Proxy {
    /// The port it listens on.
    pub port: u16,
    state: Arc<State>,
    acceptor: Option<JoinHandle<()>>,
}

impl Proxy {
    /// Starts a proxy to `upstream` that delays each direction by `delay`.
    pub fn start(upstream: SocketAddr, delay: Duration) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        listener.set_nonblocking(true).unwrap();
        let port = listener.local_addr().unwrap().port();
        let state = Arc::new(State::default());
        let st = Arc::clone(&state);
        let acceptor = std::thread::spawn(move || {
            while !st.stop.load(Ordering::Relaxed) {
                let Ok((down, _)) = listener.accept() else {
                    std::thread::sleep(Duration::from_millis(2));
                    continue;
                };
                if st.mode.load(Ordering::Relaxed) == CUT {
                    let _ = down.shutdown(Shutdown::Both);
                    continue;
                }
                let Ok(up) = TcpStream::connect(upstream) else {
                    let _ = down.shutdown(Shutdown::Both);
                    continue;
                };
                down.set_nonblocking(false).unwrap();
                for s in [&down, &up] {
                    s.set_nodelay(true).unwrap();
                    st.streams.lock().unwrap().push(s.try_clone().unwrap());
                }
                pump(down.try_clone().unwrap(), up.try_clone().unwrap(), delay, Arc::clone(&st));
                pump(up, down, delay, Arc::clone(&st));
            }
        });
        Self { port, state, acceptor: Some(acceptor) }
    }

    /// `tcp/127.0.0.1:PORT`.
    pub fn endpoint(&self) -> String {
        format!("tcp/127.0.0.1:{}", self.port)
    }

    /// Forward nothing from now on, keeping the connections open.
    pub fn stall(&self) {
        self.state.mode.store(STALL, Ordering::Relaxed);
    }

    /// Close every connection and refuse new ones.
    pub fn cut(&self) {
        self.state.mode.store(CUT, Ordering::Relaxed);
        self.state.close_all();
    }
}

impl Drop for Proxy {
    fn drop(&mut self) {
        self.state.stop.store(true, Ordering::Relaxed);
        self.state.close_all();
        if let Some(a) = self.acceptor.take() {
            let _ = a.join();
        }
    }
}

/// Copies `from` → `to`, each chunk after `delay`: a reader thread stamps chunks, a writer
/// thread writes each at its time.
fn pump(mut from: TcpStream, mut to: TcpStream, delay: Duration, st: Arc<State>) {
    let (tx, rx) = channel::<(Instant, Vec<u8>)>();
    let st2 = Arc::clone(&st);
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 64 * 1024];
        loop {
            while st.mode.load(Ordering::Relaxed) == STALL && !st.stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(1));
            }
            match from.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(k) => {
                    if tx.send((Instant::now() + delay, buf[..k].to_vec())).is_err() {
                        break;
                    }
                }
            }
        }
    });
    std::thread::spawn(move || write_due(&rx, &mut to, &st2));
}

fn write_due(rx: &Receiver<(Instant, Vec<u8>)>, to: &mut TcpStream, st: &State) {
    while let Ok((due, bytes)) = rx.recv() {
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        while st.mode.load(Ordering::Relaxed) == STALL && !st.stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(1));
        }
        if st.mode.load(Ordering::Relaxed) != FORWARD || to.write_all(&bytes).is_err() {
            break;
        }
    }
    let _ = to.shutdown(Shutdown::Both);
}
