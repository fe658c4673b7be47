//! What the listener and every client thread share: the session and image, the options,
//! the log, the open connections and the stop flag.

use std::collections::HashMap;
use std::net::TcpStream;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::log::Log;
use crate::options::Options;
use crate::state::Brainshift;

/// What every client thread shares.
#[derive(Debug)]
pub struct Shared {
    /// The session and image.
    pub brainshift: Brainshift,
    /// The options.
    pub options: Options,
    /// The log.
    pub log: Log,
    stop: AtomicBool,
    /// The open connections (a handle each, to close them when stopping).
    pub clients: Mutex<HashMap<u64, TcpStream>>,
}

impl Shared {
    /// Shared state of a server that has not stopped.
    pub fn new(brainshift: Brainshift, options: Options, log: Log) -> Shared {
        Shared {
            brainshift,
            options,
            log,
            stop: AtomicBool::new(false),
            clients: Mutex::new(HashMap::new()),
        }
    }

    /// Marks the server as stopping.
    pub fn set_stopping(&self) {
        self.stop.store(true, Ordering::SeqCst);
    }

    /// Whether the server is stopping.
    pub fn stopping(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }
}
