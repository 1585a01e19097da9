//! `rig monitor`: a watcher process for live operation of one or more rigs.
//!
//! It subscribes to each rig's telemetry ([`ipc_types::telemetry`]), one reader thread per
//! rig ([`reader`]) filling the rig's [`state`], and serves it over HTTP on a loopback
//! address by default ([`http`]): a web page with a live scope ([`page`]), the state as
//! JSON ([`snapshot`]), Prometheus metrics ([`metrics`]) and, with `--allow-commands`,
//! operator commands to the service ([`commands`]). With `--foxglove ADDR` it also serves
//! Foxglove's WebSocket protocol ([`foxglove`]). It is a separate process that the service
//! knows nothing of: it keeps working when the service restarts or the run ends (the last
//! run's final state stays on show until a new run starts), and the service runs the same
//! whether it is there or not. docs/monitor.md is the user's guide.
//!
//! - [`state`]: what is kept per rig, and the [`Hub`] of all rigs.
//! - [`counters`]: the run report's counters by name.
//! - [`reader`]: the reader thread per rig.
//! - [`snapshot`]: the JSON views of `/api/state` and `/api/points`.
//! - [`metrics`]: `/metrics` (prometheus-client collector).
//! - [`http`]: the routes.
//! - [`page`]: the web page.
//! - [`placement`]: keeping off the services' real-time cores.
//! - [`commands`]: operator commands by name (also `rig command`).
//! - [`foxglove`]: the Foxglove WebSocket server.

pub mod commands;
pub mod counters;
pub mod foxglove;
pub mod http;
pub mod metrics;
pub mod page;
pub mod placement;
pub mod reader;
pub mod snapshot;
pub mod state;

use self::foxglove::FoxgloveBridge;
use self::reader::FrameObserver;
use self::state::Hub;
use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

/// The default `--listen` address: loopback only.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:9187";

/// What `rig monitor` was asked for.
#[derive(Debug, Clone)]
pub struct MonitorOptions {
    /// The rigs to watch (`--rig`, at least one).
    pub rigs: Vec<String>,
    /// The HTTP address (`--listen`; port 0: any free port).
    pub listen: String,
    /// Forward operator commands (`--allow-commands`).
    pub allow_commands: bool,
    /// Serve Foxglove's WebSocket protocol on this address (`--foxglove`).
    pub foxglove: Option<String>,
    /// How long a command waits for its reply.
    pub command_timeout: Duration,
    /// Stay on any core, even a service's real-time core (`--any-core`; [`placement`]).
    pub any_core: bool,
}

impl Default for MonitorOptions {
    fn default() -> Self {
        Self {
            rigs: Vec::new(),
            listen: DEFAULT_LISTEN.to_string(),
            allow_commands: false,
            foxglove: None,
            command_timeout: commands::COMMAND_TIMEOUT,
            any_core: false,
        }
    }
}

/// Why the monitor could not start.
#[derive(Debug, thiserror::Error)]
pub enum MonitorError {
    /// A `--rig` that cannot be watched.
    #[error("--rig {rig}: {why}")]
    Rig {
        /// The name given.
        rig: String,
        /// What is wrong with it.
        why: String,
    },
    /// An address that cannot be served.
    #[error("{option} {addr}: {why}")]
    Address {
        /// `--listen` or `--foxglove`.
        option: &'static str,
        /// The address given.
        addr: String,
        /// Why.
        why: String,
    },
    /// The runtime or a thread could not be started.
    #[error("starting the monitor: {0}")]
    Start(String),
}

/// Resolves `addr` (`HOST:PORT`) to the first socket address it names.
fn resolve(option: &'static str, addr: &str) -> Result<SocketAddr, MonitorError> {
    let err = |why: String| MonitorError::Address {
        option,
        addr: addr.to_string(),
        why,
    };
    addr.to_socket_addrs()
        .map_err(|e| err(format!("not a HOST:PORT address ({e})")))?
        .next()
        .ok_or_else(|| err("names no address".into()))
}

/// Checks the rig names: valid in a service name, and each once.
fn check_rigs(rigs: &[String]) -> Result<(), MonitorError> {
    if rigs.is_empty() {
        return Err(MonitorError::Rig {
            rig: String::new(),
            why: "name at least one rig".into(),
        });
    }
    for (i, rig) in rigs.iter().enumerate() {
        ipc_types::telemetry::ports::telemetry_service_names(rig).map_err(|e| {
            MonitorError::Rig {
                rig: rig.clone(),
                why: e.to_string(),
            }
        })?;
        if rigs[..i].contains(rig) {
            return Err(MonitorError::Rig {
                rig: rig.clone(),
                why: "given twice".into(),
            });
        }
    }
    Ok(())
}

/// A running monitor: its runtime, HTTP server, Foxglove server and reader threads.
pub struct Monitor {
    runtime: tokio::runtime::Runtime,
    hub: Arc<Hub>,
    http_addr: SocketAddr,
    foxglove: Option<Arc<FoxgloveBridge>>,
    stop: Arc<AtomicBool>,
    readers: Vec<JoinHandle<()>>,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    server: Option<tokio::task::JoinHandle<std::io::Result<()>>>,
    /// `SIGTERM` and `SIGINT`, caught from [`Monitor::start`] on: a signal sent as soon as
    /// the monitor has said where it listens stops it cleanly instead of killing it.
    signals: (tokio::signal::unix::Signal, tokio::signal::unix::Signal),
}

impl core::fmt::Debug for Monitor {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Monitor")
            .field("rigs", &self.hub.names())
            .field("http", &self.http_addr)
            .field("foxglove", &self.foxglove_addr())
            .finish()
    }
}

impl Monitor {
    /// Checks `opts`, binds the addresses and starts everything; returns at once.
    ///
    /// # Errors
    ///
    /// A bad rig name, an address that cannot be bound, or a runtime or thread that could
    /// not be started.
    pub fn start(opts: &MonitorOptions) -> Result<Self, MonitorError> {
        check_rigs(&opts.rigs)?;
        let listen = resolve("--listen", &opts.listen)?;
        let fox_addr = match &opts.foxglove {
            Some(a) => Some(resolve("--foxglove", a)?),
            None => None,
        };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("rig-monitor")
            .enable_all()
            .build()
            .map_err(|e| MonitorError::Start(format!("the async runtime: {e}")))?;
        let hub = Arc::new(Hub::new(&opts.rigs));

        let listener = runtime
            .block_on(tokio::net::TcpListener::bind(listen))
            .map_err(|e| MonitorError::Address {
                option: "--listen",
                addr: opts.listen.clone(),
                why: e.to_string(),
            })?;
        let http_addr = listener
            .local_addr()
            .map_err(|e| MonitorError::Start(format!("the HTTP listener's address: {e}")))?;

        let foxglove = match fox_addr {
            Some(addr) => Some(
                runtime
                    .block_on(FoxgloveBridge::start(
                        hub.clone(),
                        addr,
                        opts.allow_commands,
                        opts.command_timeout,
                    ))
                    .map_err(|why| MonitorError::Address {
                        option: "--foxglove",
                        addr: opts.foxglove.clone().unwrap_or_default(),
                        why,
                    })?,
            ),
            None => None,
        };

        let stop = Arc::new(AtomicBool::new(false));
        let observers: Vec<Arc<dyn FrameObserver>> = foxglove
            .iter()
            .map(|f| f.clone() as Arc<dyn FrameObserver>)
            .collect();
        let mut readers = Vec::new();
        for i in 0..hub.names().len() {
            let h = reader::spawn(
                hub.clone(),
                i,
                stop.clone(),
                observers.clone(),
                !opts.any_core,
            )
            .map_err(|e| {
                MonitorError::Start(format!("the reader of rig '{}': {e}", hub.names()[i]))
            })?;
            readers.push(h);
        }

        let app = http::AppState {
            hub: hub.clone(),
            allow_commands: opts.allow_commands,
            foxglove: foxglove.as_ref().map(|f| f.addr().to_string()),
            registry: Arc::new(metrics::registry(hub.clone())),
            command_timeout: opts.command_timeout,
        };
        let signals = {
            use tokio::signal::unix::{SignalKind, signal};
            let _in_runtime = runtime.enter();
            let handler = |kind, name: &str| {
                signal(kind).map_err(|e| MonitorError::Start(format!("the {name} handler: {e}")))
            };
            (
                handler(SignalKind::terminate(), "SIGTERM")?,
                handler(SignalKind::interrupt(), "SIGINT")?,
            )
        };
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let server = runtime.spawn(async move {
            axum::serve(listener, http::router(app))
                .with_graceful_shutdown(async {
                    let _ = rx.await;
                })
                .await
        });
        Ok(Self {
            runtime,
            hub,
            http_addr,
            foxglove,
            stop,
            readers,
            shutdown: Some(tx),
            server: Some(server),
            signals,
        })
    }

    /// The HTTP address it listens on.
    pub fn http_addr(&self) -> SocketAddr {
        self.http_addr
    }

    /// The Foxglove WebSocket address, when it serves one.
    pub fn foxglove_addr(&self) -> Option<SocketAddr> {
        self.foxglove.as_ref().map(|f| f.addr())
    }

    /// Every rig's state.
    pub fn hub(&self) -> &Arc<Hub> {
        &self.hub
    }

    /// Blocks until `SIGINT` or `SIGTERM` (caught since [`Monitor::start`]), or until the
    /// HTTP server ends on its own.
    ///
    /// # Errors
    ///
    /// The server failed.
    pub fn wait_for_signal(&mut self) -> Result<(), MonitorError> {
        let server = self.server.as_mut();
        let (term, int) = &mut self.signals;
        self.runtime.block_on(async {
            let ended = async {
                match server {
                    Some(s) => s.await,
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                _ = int.recv() => Ok(()),
                _ = term.recv() => Ok(()),
                r = ended => match r {
                    Ok(Ok(())) => Ok(()),
                    Ok(Err(e)) => Err(MonitorError::Start(format!("the HTTP server: {e}"))),
                    Err(e) => Err(MonitorError::Start(format!("the HTTP server's task: {e}"))),
                },
            }
        })
    }

    /// Stops the servers and the readers and waits for them (at most a few seconds for
    /// the HTTP connections still open).
    pub fn shutdown(mut self) {
        if let Some(tx) = self.shutdown.take() {
            let _ = tx.send(());
        }
        let server = self.server.take();
        let fox = self.foxglove.clone();
        self.runtime.block_on(async {
            if let Some(s) = server {
                let _ = tokio::time::timeout(Duration::from_secs(3), s).await;
            }
            if let Some(f) = fox {
                let _ = tokio::time::timeout(Duration::from_secs(3), f.stop()).await;
            }
        });
        self.stop.store(true, Ordering::Relaxed);
        for r in self.readers.drain(..) {
            let _ = r.join();
        }
        self.runtime.shutdown_timeout(Duration::from_secs(1));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigs_are_checked_before_anything_starts() {
        assert!(check_rigs(&[]).is_err());
        assert!(
            check_rigs(&["a".into(), "a".into()])
                .unwrap_err()
                .to_string()
                .contains("given twice")
        );
        let e = check_rigs(&["bad name/x".into()]).unwrap_err().to_string();
        assert!(e.starts_with("--rig bad name/x: "), "{e}");
        assert!(check_rigs(&["a".into(), "b".into()]).is_ok());
    }

    #[test]
    fn a_bad_address_names_its_option() {
        let e = resolve("--listen", "nowhere").unwrap_err().to_string();
        assert!(e.starts_with("--listen nowhere: "), "{e}");
    }
}
