//! The listening socket and one thread per client (std threads: a handful of clients, each
//! mostly waiting, and updates one at a time). The accept loop polls a stop flag, so Ctrl-C
//! (or [`Server::stop`]) closes every connection and joins every thread; more clients than
//! the cap are answered with an `Error` and closed.

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::log::Log;
use crate::options::Options;
use crate::replies::{Wire, send_error};
use crate::shared::Shared;
use crate::state::Brainshift;

/// A bound server (see the module documentation).
#[derive(Debug)]
pub struct Server {
    shared: Arc<Shared>,
    listener: TcpListener,
    threads: Mutex<Vec<std::thread::JoinHandle<()>>>,
}

impl Server {
    /// Prepares the session and the image of `options` and binds its address.
    pub fn bind(options: &Options, log: Log) -> Result<Server, String> {
        let brainshift = Brainshift::new(options, log.clone())?;
        let listener = TcpListener::bind((options.host.as_str(), options.port))
            .map_err(|e| format!("{}:{}: {e}", options.host, options.port))?;
        listener.set_nonblocking(true).map_err(|e| e.to_string())?;
        let shared = Arc::new(Shared::new(brainshift, options.clone(), log));
        Ok(Server { shared, listener, threads: Mutex::new(Vec::new()) })
    }

    /// The address it listens on.
    pub fn address(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// The session and image.
    pub fn brainshift(&self) -> &Brainshift {
        &self.shared.brainshift
    }

    /// Accepts clients until `stop` is set (or [`Server::stop`] is called), then closes
    /// every connection and joins every client thread.
    pub fn serve(&self, stop: &AtomicBool) {
        let mut next = 1u64;
        while !stop.load(Ordering::SeqCst) && !self.shared.stopping() {
            match self.listener.accept() {
                Ok((stream, peer)) => {
                    self.accept(next, stream, peer);
                    next += 1;
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    std::thread::sleep(Duration::from_millis(50));
                }
                Err(e) => self.shared.log.line(&format!("accept: {e}")),
            }
            self.reap();
        }
        self.stop();
    }

    /// Closes every connection and joins every client thread.
    pub fn stop(&self) {
        self.shared.set_stopping();
        for c in self.shared.clients.lock().unwrap_or_else(|e| e.into_inner()).values() {
            let _ = c.shutdown(std::net::Shutdown::Both);
        }
        let threads = std::mem::take(&mut *self.threads.lock().unwrap_or_else(|e| e.into_inner()));
        for t in threads {
            let _ = t.join();
        }
    }

    /// Joins the threads of clients that have left.
    fn reap(&self) {
        let mut threads = self.threads.lock().unwrap_or_else(|e| e.into_inner());
        let (done, running): (Vec<_>, Vec<_>) = threads.drain(..).partition(|t| t.is_finished());
        *threads = running;
        for t in done {
            let _ = t.join();
        }
    }

    fn accept(&self, k: u64, stream: TcpStream, peer: SocketAddr) {
        let shared = &self.shared;
        let _ = stream.set_nonblocking(false);
        let _ = stream.set_nodelay(true);
        let mut clients = shared.clients.lock().unwrap_or_else(|e| e.into_inner());
        if clients.len() >= shared.options.max_clients {
            drop(clients);
            let cap = shared.options.max_clients;
            shared.log.line(&format!("refused {peer}: {cap} clients already connected"));
            let text = format!("the server already serves {cap} clients; try again later");
            let mut s = stream;
            let _ = send_error(&mut s, &mut Wire::default(), &text);
            return;
        }
        let Ok(handle) = stream.try_clone() else { return };
        clients.insert(k, handle);
        drop(clients);
        let shared = Arc::clone(shared);
        let spawned = std::thread::Builder::new().name(format!("client {k}")).spawn(move || {
            let name = format!("client {k} ({peer})");
            shared.log.line(&format!("{name} connected"));
            crate::client::serve(&shared, stream, &name);
            shared.clients.lock().unwrap_or_else(|e| e.into_inner()).remove(&k);
            shared.log.line(&format!("{name} disconnected"));
        });
        match spawned {
            Ok(t) => self.threads.lock().unwrap_or_else(|e| e.into_inner()).push(t),
            Err(e) => {
                self.shared.clients.lock().unwrap_or_else(|e| e.into_inner()).remove(&k);
                self.shared.log.line(&format!("could not start a thread for {peer}: {e}"));
            }
        }
    }
}

/// Set by Ctrl-C (SIGINT) and SIGTERM once [`run`] has installed the handler.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);
static HANDLER: std::sync::Once = std::sync::Once::new();

/// `brainshift serve`: prepares, listens, serves until Ctrl-C or SIGTERM, stops cleanly;
/// the lines a user reads go to `log`. An error before listening (the scene, the image,
/// `--set`, the address) is returned, for the front end to print.
pub fn run(options: &Options, log: Log) -> Result<(), String> {
    log.line(&format!(
        "preparing {} and reading {} ...",
        options.scene.display(),
        options.image.display()
    ));
    let server = Server::bind(options, log.clone())?;
    let bs = server.brainshift();
    let [nx, ny, nz] = bs.image.grid.dims();
    let moves = match &bs.set {
        Some(s) => format!("measurements move node set {s} ({} nodes)", bs.set_size()),
        None => "no prescribed node set: measurements are scans to fit (IntraopPoints)".into(),
    };
    log.line(&format!("prepared in {:.2} s: {nx}x{ny}x{nz} image, {moves}", bs.prepare_seconds));
    let address = server.address().map_err(|e| e.to_string())?;
    log.line(&format!("listening on {address} (OpenIGTLink); Ctrl-C stops"));
    HANDLER.call_once(|| {
        if let Err(e) = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::SeqCst)) {
            eprintln!("warning: Ctrl-C cannot be caught ({e}); stop the server with SIGKILL");
        }
    });
    INTERRUPTED.store(false, Ordering::SeqCst);
    server.serve(&INTERRUPTED);
    log.line("stopping ...");
    server.stop();
    log.line("stopped");
    Ok(())
}
