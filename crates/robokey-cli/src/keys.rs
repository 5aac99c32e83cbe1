//! `robokey keys`: the final keys of an agent's store (docs/postprocessing.md, "Key store").

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Subcommand};
use robokey_net::key_store::{KeyStore, StoredKey};
use robokey_net::post_store::lock_store;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct KeysArgs {
    #[command(subcommand)]
    command: KeysCommand,
}

#[derive(Subcommand, Debug)]
enum KeysCommand {
    /// List the final keys of a store: ID, length, ε, label, creation time, sessions, and the
    /// assumption about Eve each is secret under. Never prints key bits.
    List {
        /// The store (an agent's --store).
        #[arg(long)]
        store: PathBuf,
        /// As JSON (one object per key, without its bits).
        #[arg(long)]
        json: bool,
    },
    /// Print a key's bits as hex on stdout (most significant bit first, the last byte
    /// zero-padded to the key's length).
    Get {
        /// The store.
        #[arg(long)]
        store: PathBuf,
        /// The key's ID (16 hex digits, the same on the robot and the controller).
        id: String,
    },
    /// Delete a key from the store (refused while an agent holds the store).
    Delete {
        /// The store.
        #[arg(long)]
        store: PathBuf,
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
    assumption: &'a str,
    created: &'a str,
    sessions: &'a [u32],
}

impl<'a> From<&'a StoredKey> for Listed<'a> {
    fn from(key: &'a StoredKey) -> Self {
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
            assumption: &key.assumption,
            created: &key.created,
            sessions: &key.sessions,
        }
    }
}

pub fn keys(args: KeysArgs) -> Result<()> {
    match args.command {
        KeysCommand::List { store, json } => {
            let keys = KeyStore::open(&store)?.list()?;
            let listed: Vec<Listed<'_>> = keys.iter().map(Listed::from).collect();
            if json {
                println!("{}", serde_json::to_string_pretty(&listed)?);
            } else {
                print!("{}", table(&listed));
            }
        }
        KeysCommand::Get { store, id } => {
            let key = KeyStore::open(&store)?.get(&id)?;
            println!("{}", key.hex);
        }
        KeysCommand::Delete { store, id } => {
            let keys = KeyStore::open(&store)?;
            let _lock = lock_store(&store)?;
            keys.delete(&id)?;
            eprintln!("deleted key {id} from {}", store.display());
        }
    }
    Ok(())
}

/// One line per key, then each assumption once.
fn table(keys: &[Listed<'_>]) -> String {
    if keys.is_empty() {
        return "no keys\n".to_owned();
    }
    let mut assumptions: Vec<&str> = Vec::new();
    let mut out = format!(
        "{:<16}  {:>7}  {:>7}  {:<10}  {:<20}  {:>8}  assumption\n",
        "ID", "bits", "ε", "label", "created", "sessions"
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
            "{:<16}  {:>7}  {:>7.0e}  {:<10}  {:<20}  {:>8}  [{}]\n",
            key.id,
            key.bits,
            key.epsilon,
            key.label,
            key.created,
            key.sessions.len(),
            number + 1
        ));
    }
    for (i, assumption) in assumptions.iter().enumerate() {
        out.push_str(&format!("[{}] {assumption}\n", i + 1));
    }
    out
}
