//! `robokey kme`: an ETSI GS QKD 014 key-delivery server on an agent's store (docs/keys.md).
//! The controller's store gives new keys (`enc_keys`), the robot's the same keys by their IDs
//! (`dec_keys`), each once, to the one application whose client certificate names it.

use std::io::Write as _;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Result;
use clap::Args;
use robokey_net::key_delivery::KeyDelivery;
use robokey_net::kme::api::{KeyApi, KmeIdentity};
use robokey_net::kme::server::KmeServer;
use robokey_net::kme::tls::{TlsFiles, server_config};

use crate::exit::{Status, on_signals, usage};
use crate::keys::StoreArgs;

/// Longest SAE ID (characters).
const MAX_SAE_ID: usize = 64;

#[derive(Args, Debug)]
pub struct KmeArgs {
    #[command(flatten)]
    store: StoreArgs,
    /// Address to serve HTTPS on. Loopback by default: the application runs on this host.
    #[arg(long, default_value = "127.0.0.1:8443")]
    listen: SocketAddr,
    /// The server's certificate chain (PEM), its own certificate first.
    #[arg(long, value_name = "FILE")]
    tls_cert: PathBuf,
    /// The server's private key (PEM; readable by this user only).
    #[arg(long, value_name = "FILE")]
    tls_key: PathBuf,
    /// The CA that signs the application's client certificate (PEM): a client without a
    /// certificate from it fails the TLS handshake.
    #[arg(long, value_name = "FILE")]
    client_ca: PathBuf,
    /// The local application's SAE ID: the subject common name its client certificate must
    /// carry (401 otherwise). Letters, digits and `._~-`, at most 64.
    #[arg(long, value_name = "SELF")]
    sae_id: String,
    /// The SAE ID of the application at the other end: the `{SAE_ID}` of the URLs (the
    /// slave for enc_keys on the controller side, the master for dec_keys on the robot side).
    #[arg(long, value_name = "PEER")]
    peer_sae_id: String,
}

/// Serves until SIGINT or SIGTERM.
pub fn kme(args: KmeArgs) -> Result<Status> {
    for (flag, id) in [
        ("--sae-id", &args.sae_id),
        ("--peer-sae-id", &args.peer_sae_id),
    ] {
        let allowed = |c: char| c.is_ascii_alphanumeric() || "._~-".contains(c);
        if id.is_empty() || id.chars().count() > MAX_SAE_ID || !id.chars().all(allowed) {
            usage!(
                "{flag} {id:?}: an SAE ID is 1 to {MAX_SAE_ID} letters, digits and `._~-` (it \
                 is a path segment of the ETSI URLs)"
            );
        }
    }
    if args.sae_id == args.peer_sae_id {
        usage!(
            "--sae-id and --peer-sae-id are both {:?}: they name the two ends",
            args.sae_id
        );
    }
    let pairing = args.store.pairing()?;
    let delivery = KeyDelivery::open(&args.store.store, &pairing)?;
    let side = delivery.side();
    let fingerprint = pairing.fingerprint();
    let identity = KmeIdentity {
        sae: args.sae_id.clone(),
        peer_sae: args.peer_sae_id.clone(),
        kme: format!("robokey-{}-{fingerprint}", side.name()),
        peer_kme: format!("robokey-{}-{fingerprint}", side.peer().name()),
    };
    let tls = server_config(TlsFiles {
        cert: &args.tls_cert,
        key: &args.tls_key,
        client_ca: &args.client_ca,
    })?;
    let server = KmeServer::bind(args.listen, tls, KeyApi::new(delivery, identity))?;
    let address = server.local_addr()?;
    if !address.ip().is_loopback() {
        eprintln!(
            "kme: listening beyond this host ({address}): only a client certificate from \
             --client-ca naming {} gets keys, but keep the port firewalled",
            args.sae_id
        );
    }
    let role = match side {
        robokey_net::key_delivery::Side::Controller => {
            "controller side (ETSI master's KME: new keys with enc_keys)"
        }
        robokey_net::key_delivery::Side::Robot => {
            "robot side (ETSI slave's KME: keys by ID with dec_keys)"
        }
    };
    println!(
        "kme: {role} of store {}, for SAE {} with SAE {}, HTTPS on {address}",
        args.store.store.display(),
        args.sae_id,
        args.peer_sae_id
    );
    std::io::stdout().flush()?;
    let interrupt = on_signals()?;
    // A log line that cannot be written (stdout closed) is dropped, never a panic.
    let log: Arc<dyn Fn(&str) + Send + Sync> = Arc::new(|line: &str| {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "kme: {line}").and_then(|()| out.flush());
    });
    server.serve(&interrupt, &log)?;
    Ok(Status::Interrupted(interrupt.signal().unwrap_or(2)))
}
