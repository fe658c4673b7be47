//! brainshift in the operating room: `brainshift serve`, a native OpenIGTLink server (3D
//! Slicer's OpenIGTLinkIF, PLUS, navigation systems) over a live, in-memory session of a
//! scene. The scene is prepared and the pre-operative image read once; each measurement a
//! client sends becomes a typed `bs_scene::Update` ([`measure`], in the scene's frame and
//! unit: [`frame`]), is solved warm from the last good state ([`state`]) and answered to that
//! client ([`replies`]: the warped image first). Protocol bytes are bs-igtl's; the
//! connection loop is [`client`], the listener and its threads [`server`], the options
//! (declared once, for the binary and the Python package) [`options`].
//!
//! Nothing the clients send stops the server: a refused measurement, a load the solver
//! cannot carry or a result that fails verification is answered with STRING `Error` and the
//! session stays at its last good state; a stream that cannot be read on is answered and
//! that connection closed.

pub mod client;
pub mod frame;
pub mod log;
pub mod measure;
pub mod options;
pub mod replies;
pub mod server;
pub mod shared;
pub mod state;

pub use log::Log;
pub use options::{Command, Options};
pub use server::{Server, run};
