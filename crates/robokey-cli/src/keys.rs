//! `robokey keys`: the final keys of an agent's store (docs/postprocessing.md, "Key store").
//! Every key file is verified under the pairing's store key before it is listed or given out,
//! and a pending key is listed but never given out.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Subcommand};
use robokey_net::key_store::{KeyStatus, KeyStore, StoredKey};
use robokey_net::post_store::{lock_store, open_keys};
use serde::Serialize;

#[derive(Args, Debug)]
pub struct KeysArgs {
    #[command(subcommand)]
    command: KeysCommand,
}

/// The store and the pairing that verifies it.
#[derive(Args, Debug)]
struct StoreArgs {
    /// The store (an agent's --store).
    #[arg(long)]
    store: PathBuf,
    /// The pairing file of the store's agent: key files are verified under a key derived
    /// from it, so a file planted or edited beside the store is refused.
    #[arg(long, value_name = "FILE")]
    pairing: PathBuf,
    /// Use a pairing file that group or others may read or write, or that another user owns.
    #[arg(long)]
    insecure_pairing_file: bool,
}

impl StoreArgs {
    fn keys(&self) -> Result<KeyStore> {
        let pairing = crate::net::pairing_from(&self.pairing, self.insecure_pairing_file)?;
        Ok(open_keys(&self.store, &pairing)?)
    }
}

#[derive(Subcommand, Debug)]
enum KeysCommand {
    /// List the final keys of a store: ID, length, ε, label, status (settled, or pending and
    /// why), creation time, sessions, and the assumption about Eve each is secret under.
    /// Never prints key bits.
    List {
        #[command(flatten)]
        store: StoreArgs,
        /// As JSON (one object per key, without its bits).
        #[arg(long)]
        json: bool,
    },
    /// Print a settled key's bits as hex on stdout (most significant bit first, the last byte
    /// zero-padded to the key's length). A pending key — one the peer has not acknowledged —
    /// is withheld (exit 5).
    Get {
        #[command(flatten)]
        store: StoreArgs,
        /// The key's ID (16 hex digits, the same on the robot and the controller).
        id: String,
    },
    /// Delete a settled key from the store (refused while an agent holds the store, and for
    /// a pending key: exit 5).
    Delete {
        #[command(flatten)]
        store: StoreArgs,
        /// The key's ID.
        id: String,
    },
}

/// A key as listed: everything but its bits.
#[derive(Serialize)]
struct Listed<'a> {
    id: &'a str,
    role: &'a str,
    block: u64,
    bits: usize,
    epsilon: f64,
    label: &'static str,
    status: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pending_reason: Option<&'a str>,
    assumption: &'a str,
    created: &'a str,
    sessions: &'a [u32],
}

impl<'a> From<&'a StoredKey> for Listed<'a> {
    fn from(key: &'a StoredKey) -> Self {
        let (status, pending_reason) = match &key.status {
            KeyStatus::Settled => ("settled", None),
            KeyStatus::Pending(reason) => ("pending", Some(reason.as_str())),
        };
        Self {
            id: &key.id,
            role: &key.role,
            block: key.block,
            bits: key.bits,
            epsilon: key.epsilon,
            label: if key.restricted {
                "restricted"
            } else {
                "physical"
            },
            status,
            pending_reason,
            assumption: &key.assumption,
            created: &key.created,
            sessions: &key.sessions,
        }
    }
}

pub fn keys(args: KeysArgs) -> Result<()> {
    match args.command {
        KeysCommand::List { store, json } => {
            let keys = store.keys()?.list()?;
            let listed: Vec<Listed<'_>> = keys.iter().map(Listed::from).collect();
            if json {
                println!("{}", serde_json::to_string_pretty(&listed)?);
            } else {
                print!("{}", table(&listed));
            }
        }
        KeysCommand::Get { store, id } => {
            let key = store.keys()?.deliver(&id)?;
            println!("{}", key.hex);
        }
        KeysCommand::Delete { store, id } => {
            let keys = store.keys()?;
            let _lock = lock_store(&store.store)?;
            keys.delete(&id)?;
            eprintln!("deleted key {id} from {}", store.store.display());
        }
    }
    Ok(())
}

/// One line per key, then each assumption once, then why each pending key is pending.
fn table(keys: &[Listed<'_>]) -> String {
    if keys.is_empty() {
        return "no keys\n".to_owned();
    }
    let mut assumptions: Vec<&str> = Vec::new();
    let mut out = format!(
        "{:<16}  {:>7}  {:>7}  {:<10}  {:<8}  {:<20}  {:>8}  assumption\n",
        "ID", "bits", "ε", "label", "status", "created", "sessions"
    );
    for key in keys {
        let number = match assumptions.iter().position(|a| *a == key.assumption) {
            Some(i) => i,
            None => {
                assumptions.push(key.assumption);
                assumptions.len() - 1
            }
        };
        out.push_str(&format!(
            "{:<16}  {:>7}  {:>7.0e}  {:<10}  {:<8}  {:<20}  {:>8}  [{}]\n",
            key.id,
            key.bits,
            key.epsilon,
            key.label,
            key.status,
            key.created,
            key.sessions.len(),
            number + 1
        ));
    }
    for (i, assumption) in assumptions.iter().enumerate() {
        out.push_str(&format!("[{}] {assumption}\n", i + 1));
    }
    for key in keys {
        if let Some(reason) = key.pending_reason {
            out.push_str(&format!(
                "{} is pending: {reason}; withheld from `keys get` until settled\n",
                key.id
            ));
        }
    }
    out
}
