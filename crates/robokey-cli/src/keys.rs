//! `robokey keys`: the final keys of an agent's store (docs/postprocessing.md, "Key store")
//! and the keys cut from them for applications (docs/keys.md). Every key file is verified
//! under the pairing's store key before it is listed or taken from, a pending key is listed
//! but never given out, and a key taken is never given out again.

use std::io::{IsTerminal as _, Write as _};
use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Subcommand, ValueEnum};
use robokey::protocol::auth::PairingSecret;
use robokey_net::key_delivery::{KeyDelivery, Side};
use robokey_net::key_listing::ListedKey;
use robokey_net::key_slice::{DEFAULT_SLICE_BITS, SliceId};
use robokey_net::key_store::KeyStore;
use robokey_net::post_store::{lock_store, open_keys};

use crate::exit::usage;

#[derive(Args, Debug)]
pub struct KeysArgs {
    #[command(subcommand)]
    command: KeysCommand,
}

/// The store and the pairing that verifies it.
#[derive(Args, Debug)]
pub(crate) struct StoreArgs {
    /// The store (an agent's --store; the agent may be running).
    #[arg(long)]
    pub(crate) store: PathBuf,
    /// The pairing file of the store's agent: key files are verified under a key derived
    /// from it, so a file planted or edited beside the store is refused.
    #[arg(long, value_name = "FILE")]
    pairing: PathBuf,
    /// Use a pairing file that group or others may read or write, or that another user owns.
    #[arg(long)]
    insecure_pairing_file: bool,
}

impl StoreArgs {
    /// The pairing secret, from a file checked as the agents check it.
    pub(crate) fn pairing(&self) -> Result<PairingSecret> {
        crate::net::pairing_from(&self.pairing, self.insecure_pairing_file)
    }

    /// The store's key folder, verified under the pairing.
    pub(crate) fn keys(&self) -> Result<KeyStore> {
        Ok(open_keys(&self.store, &self.pairing()?)?)
    }
}

/// How `keys take` writes a key.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum KeyFormat {
    /// Lowercase hex.
    Hex,
    /// Standard base64 with padding (RFC 4648), as WireGuard and the ETSI interface take it.
    Base64,
    /// The bytes alone (never onto a terminal); the key ID goes to stderr.
    Raw,
}

#[derive(Subcommand, Debug)]
enum KeysCommand {
    /// List the final keys of a store: ID, length, bits still available to take and bits
    /// taken, ε, label, status (settled, or pending and why), how its block was reconciled
    /// (cascade or ldpc) and leak_EC, creation time, sessions, and the assumption about Eve
    /// each is secret under. Never prints key bits.
    List {
        #[command(flatten)]
        store: StoreArgs,
        /// As JSON (one object per key, without its bits).
        #[arg(long)]
        json: bool,
    },
    /// Take a key for an application: its ID, then the key, on stdout (`--format raw`: the
    /// bytes alone, the ID on stderr). It is marked taken and erased from the store before it
    /// is printed, and never given out again by this store. The controller's store cuts a new
    /// key of `--bits` from the first settled final key with room (exit 3 when there is none
    /// yet); the robot's store gives a key only by the ID the controller's gave (`--id`), with
    /// the same bits. A pending final key is never cut (exit 5).
    Take {
        #[command(flatten)]
        store: StoreArgs,
        /// The key's length (bits; a multiple of 8 from 64 to 8192). Default 256 on the
        /// controller's store; on the robot's, the ID says it.
        #[arg(long)]
        bits: Option<u32>,
        /// The ID the controller's store gave the key (robot's store only): a UUID.
        #[arg(long)]
        id: Option<String>,
        /// How to write the key.
        #[arg(long, value_enum, default_value = "hex")]
        format: KeyFormat,
    },
    /// Print a whole settled final key as hex on stdout (most significant bit first, the last
    /// byte zero-padded to the key's length), to compare the two stores. This is no delivery:
    /// nothing is marked taken (applications use `keys take` or `robokey kme`), and a final
    /// key from which a key was taken is refused (its taken bits were erased). A pending key
    /// — one the peer has not acknowledged — is withheld (exit 5).
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

pub fn keys(args: KeysArgs) -> Result<()> {
    match args.command {
        KeysCommand::List { store, json } => {
            let keys = store.keys()?.list()?;
            let listed: Vec<ListedKey> = keys.iter().map(ListedKey::from).collect();
            if json {
                println!("{}", serde_json::to_string_pretty(&listed)?);
            } else {
                print!("{}", table(&listed));
            }
        }
        KeysCommand::Take {
            store,
            bits,
            id,
            format,
        } => take(&store, bits, id.as_deref(), format)?,
        KeysCommand::Get { store, id } => {
            let key = store.keys()?.settled(&id)?;
            if !key.taken.is_empty() {
                usage!(
                    "{} bits of final key {id} were taken (delivered) and erased: `keys get` \
                     gives only a final key nothing was taken from",
                    key.taken_bits()
                );
            }
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

/// Takes one key (see `KeysCommand::Take`) and writes it.
fn take(store: &StoreArgs, bits: Option<u32>, id: Option<&str>, format: KeyFormat) -> Result<()> {
    if matches!(format, KeyFormat::Raw) && std::io::stdout().is_terminal() {
        usage!("--format raw writes the key's bytes: redirect stdout to a file or a pipe");
    }
    let delivery = KeyDelivery::new(store.keys()?);
    let delivered = match (delivery.side(), id) {
        (Side::Controller, None) => delivery.take_new(bits.unwrap_or(DEFAULT_SLICE_BITS), 1)?,
        (Side::Controller, Some(_)) => usage!(
            "{} is a controller's store, which hands out new keys: drop --id (the robot's \
             store gives the same key by the ID this one prints)",
            store.store.display()
        ),
        (Side::Robot, None) => usage!(
            "{} is a robot's store, which gives a key only by the ID the controller's store \
             gave it: pass --id",
            store.store.display()
        ),
        (Side::Robot, Some(id)) => {
            let asked = SliceId::parse(id).map_err(crate::exit::Usage)?;
            if let Some(bits) = bits.filter(|&b| b != asked.span.bits) {
                usage!(
                    "--bits {bits}, but the key {id} has {} bits (drop --bits)",
                    asked.span.bits
                );
            }
            delivery.take_by_id(&[id])?
        }
    };
    let key = &delivered[0];
    let mut stdout = std::io::stdout().lock();
    match format {
        KeyFormat::Hex => writeln!(stdout, "{}\n{}", key.id, *key.hex())?,
        KeyFormat::Base64 => writeln!(stdout, "{}\n{}", key.id, *key.base64())?,
        KeyFormat::Raw => {
            stdout.write_all(&key.key)?;
            eprintln!("{}", key.id);
        }
    }
    stdout.flush()?;
    Ok(())
}

/// One line per key, then each assumption once (with the plant's model class a private
/// key rests on), then why each pending key is pending.
fn table(keys: &[ListedKey]) -> String {
    if keys.is_empty() {
        return "no keys\n".to_owned();
    }
    let mut assumptions: Vec<(&str, Option<&str>)> = Vec::new();
    let mut out = format!(
        "{:<16}  {:>7}  {:>9}  {:>7}  {:>7}  {:<10}  {:<8}  {:<10}  {:>8}  {:<20}  {:>8}  assumption\n",
        "ID",
        "bits",
        "available",
        "taken",
        "ε",
        "label",
        "status",
        "reconciled",
        "leak_EC",
        "created",
        "sessions"
    );
    for key in keys {
        let stated = (
            key.assumption.as_str(),
            key.basis.as_ref().map(|b| b.plant.as_str()),
        );
        let number = match assumptions.iter().position(|a| *a == stated) {
            Some(i) => i,
            None => {
                assumptions.push(stated);
                assumptions.len() - 1
            }
        };
        out.push_str(&format!(
            "{:<16}  {:>7}  {:>9}  {:>7}  {:>7.0e}  {:<10}  {:<8}  {:<10}  {:>8}  {:<20}  {:>8}  [{}]\n",
            key.id,
            key.bits,
            key.available_bits,
            key.taken_bits,
            key.epsilon,
            key.label,
            key.status,
            key.reconciliation.as_deref().unwrap_or("-"),
            key.leak_ec.map_or_else(|| "-".to_owned(), |leak| leak.to_string()),
            key.created,
            key.sessions.len(),
            number + 1
        ));
    }
    for (i, (assumption, plant)) in assumptions.iter().enumerate() {
        out.push_str(&format!("[{}] {assumption}\n", i + 1));
        if let Some(plant) = plant {
            out.push_str(&format!("    plant model class: {plant}\n"));
        }
    }
    for key in keys {
        if let Some(reason) = &key.pending_reason {
            out.push_str(&format!(
                "{} is pending: {reason}; nothing is taken from it until it settles\n",
                key.id
            ));
        }
    }
    out
}
