//! The worker thread that parses each input under `catch_unwind` with the allocator capped,
//! and the panic hook that records its panics (message and location) instead of printing them.

use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};

use crate::reader::Reader;

/// The panic message and location of the panic being caught on the worker thread.
pub type PanicSlot = Arc<Mutex<Option<String>>>;

pub enum Outcome {
    Parsed(bool),
    Panicked(String),
}

/// The worker thread: parses each input under `catch_unwind`, with the allocator capped.
pub struct Worker {
    pub send: mpsc::Sender<(Reader, Vec<u8>)>,
    pub recv: mpsc::Receiver<Outcome>,
}

const WORKER_NAME: &str = "bs-fuzz-worker";

impl Worker {
    pub fn start(cap_memory: bool, slot: PanicSlot) -> Worker {
        let (send, jobs) = mpsc::channel::<(Reader, Vec<u8>)>();
        let (done, recv) = mpsc::channel();
        std::thread::Builder::new()
            .name(WORKER_NAME.into())
            .spawn(move || {
                for (reader, input) in jobs {
                    if cap_memory {
                        let limit = crate::ALLOC
                            .allocated()
                            .saturating_add(input.len().saturating_mul(64))
                            .saturating_add(256 << 20);
                        let _ = crate::ALLOC.set_limit(limit);
                    }
                    let r = catch_unwind(AssertUnwindSafe(|| reader.parse(&input)));
                    if cap_memory {
                        let _ = crate::ALLOC.set_limit(usize::MAX);
                    }
                    let outcome = match r {
                        Ok(ok) => Outcome::Parsed(ok),
                        Err(payload) => Outcome::Panicked(
                            slot.lock()
                                .ok()
                                .and_then(|mut s| s.take())
                                .unwrap_or_else(|| payload_text(&payload)),
                        ),
                    };
                    if done.send(outcome).is_err() {
                        break;
                    }
                }
            })
            .expect("spawning a thread");
        Worker { send, recv }
    }
}

fn payload_text(payload: &Box<dyn Any + Send>) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic with a non-text payload".into())
}

/// Installs a panic hook that records panics of the worker thread (message and location)
/// instead of printing them, and leaves others to the previous hook.
pub fn install_hook(slot: PanicSlot) {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if std::thread::current().name() == Some(WORKER_NAME) {
            let at = info.location().map(|l| format!(" at {}:{}", l.file(), l.line()));
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_default();
            if let Ok(mut s) = slot.lock() {
                *s = Some(format!("panic '{msg}'{}", at.unwrap_or_default()));
            }
        } else {
            previous(info);
        }
    }));
}
