//! The ETSI GS QKD 014 v1.1.1 key-delivery API on one store (docs/keys.md, "The ETSI
//! interface"): `GET /api/v1/keys/{SAE_ID}/status`, `GET`/`POST …/enc_keys` on the
//! controller side (the master's KME: new keys) and `GET`/`POST …/dec_keys` on the robot side
//! (the slave's KME: the same keys by `key_ID`), with the standard's JSON containers — keys as
//! base64 under UUID `key_ID`s — and its status codes: 400 for a request that is malformed or
//! asks what this KME does not do, 401 for a client certificate that does not name the local
//! SAE, 503 when no key can be given now (none yet, pending, or the store failed).
//!
//! The caller is the local SAE (its client certificate's common name, checked by the server);
//! the `{SAE_ID}` in the path is the peer SAE: the slave for `status` and `enc_keys`, the
//! master for `dec_keys`. Keys are taken exactly as `robokey keys take` takes them.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use uuid::Uuid;
use zeroize::Zeroizing;

use super::http::{Request, Response};
use crate::error::NetError;
use crate::key_delivery::{Delivered, KeyDelivery, Side};
use crate::key_slice::{DEFAULT_SLICE_BITS, MAX_SLICE_BITS, MIN_SLICE_BITS, check_slice_bits};

/// Most keys one request may ask for (`max_key_per_request`).
pub const MAX_KEYS_PER_REQUEST: u32 = 128;
/// The path every route starts with.
const PREFIX: &str = "/api/v1/keys/";

/// Who is who around one KME.
#[derive(Clone, Debug)]
pub struct KmeIdentity {
    /// The local SAE: the common name its client certificate must carry.
    pub sae: String,
    /// The SAE at the other end, which shares the keys.
    pub peer_sae: String,
    /// This KME's ID (`source_KME_ID`).
    pub kme: String,
    /// The other side's KME ID (`target_KME_ID`).
    pub peer_kme: String,
}

/// What the API answered, for the server's log.
#[derive(Debug)]
pub struct Answer {
    /// The response to send.
    pub response: Response,
    /// The IDs of the keys it carries.
    pub keys: Vec<Uuid>,
    /// Why it is not 200, in full (the body may say less when the store failed).
    pub error: Option<String>,
}

/// The API of one store.
#[derive(Debug)]
pub struct KeyApi {
    delivery: KeyDelivery,
    identity: KmeIdentity,
}

/// The `Status` object.
#[derive(Serialize)]
struct Status<'a> {
    #[serde(rename = "source_KME_ID")]
    source_kme: &'a str,
    #[serde(rename = "target_KME_ID")]
    target_kme: &'a str,
    #[serde(rename = "master_SAE_ID")]
    master_sae: &'a str,
    #[serde(rename = "slave_SAE_ID")]
    slave_sae: &'a str,
    key_size: u32,
    stored_key_count: u64,
    max_key_count: u64,
    max_key_per_request: u32,
    max_key_size: u32,
    min_key_size: u32,
    #[serde(rename = "max_SAE_ID_count")]
    max_sae_id_count: u32,
}

/// The `Key request` object (`enc_keys` by POST).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyRequest {
    number: Option<u64>,
    size: Option<u64>,
    #[serde(rename = "additional_slave_SAE_IDs")]
    additional_slaves: Option<Vec<String>>,
    extension_mandatory: Option<Vec<Value>>,
    #[serde(rename = "extension_optional")]
    _extension_optional: Option<Vec<Value>>,
}

/// The `Key IDs` object (`dec_keys` by POST).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyIds {
    #[serde(rename = "key_IDs")]
    key_ids: Vec<KeyIdEntry>,
    #[serde(rename = "key_IDs_extension")]
    _extension: Option<Value>,
}

/// One entry of `key_IDs`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyIdEntry {
    #[serde(rename = "key_ID")]
    key_id: String,
    #[serde(rename = "key_ID_extension")]
    _extension: Option<Value>,
}

/// One key of the `Key container`.
#[derive(Serialize)]
struct KeyEntry<'a> {
    #[serde(rename = "key_ID")]
    key_id: String,
    key: &'a str,
}

/// The `Key container` object.
#[derive(Serialize)]
struct KeyContainer<'a> {
    keys: Vec<KeyEntry<'a>>,
}

/// The `Error` object.
#[derive(Serialize)]
struct ErrorBody<'a> {
    message: &'a str,
}

/// A refusal: the status and what the body says.
struct Refusal(u16, String);

impl Refusal {
    fn bad(message: impl Into<String>) -> Self {
        Self(400, message.into())
    }
}

impl KeyApi {
    /// The API of `delivery`'s store, for `identity`.
    #[must_use]
    pub fn new(delivery: KeyDelivery, identity: KmeIdentity) -> Self {
        Self { delivery, identity }
    }

    /// The store's side.
    #[must_use]
    pub fn side(&self) -> Side {
        self.delivery.side()
    }

    /// Who is who.
    #[must_use]
    pub fn identity(&self) -> &KmeIdentity {
        &self.identity
    }

    /// Answers `request` from the client whose certificate names `client` (its common name).
    #[must_use]
    pub fn answer(&self, request: &Request, client: Option<&str>) -> Answer {
        match self.route(request, client) {
            Ok((body, keys)) => Answer {
                response: Response { status: 200, body },
                keys,
                error: None,
            },
            Err(Refusal(status, message)) => Answer {
                response: error_response(status, &message),
                keys: Vec::new(),
                error: Some(message),
            },
        }
    }

    fn route(
        &self,
        request: &Request,
        client: Option<&str>,
    ) -> Result<(Zeroizing<Vec<u8>>, Vec<Uuid>), Refusal> {
        let me = &self.identity;
        if client != Some(me.sae.as_str()) {
            return Err(Refusal(
                401,
                format!(
                    "this KME serves SAE {:?} only, and the client certificate names {}",
                    me.sae,
                    client.map_or_else(|| "no common name".to_owned(), |c| format!("{c:?}"))
                ),
            ));
        }
        let (path, query) = request
            .target
            .split_once('?')
            .unwrap_or((&request.target, ""));
        let (sae, operation) = path
            .strip_prefix(PREFIX)
            .and_then(|rest| rest.split_once('/'))
            .filter(|(sae, operation)| !sae.is_empty() && !operation.contains('/'))
            .ok_or_else(|| {
                Refusal::bad(format!(
                    "no such resource {:?}: the API is {PREFIX}{{SAE_ID}}/status, enc_keys or \
                     dec_keys",
                    brief(path)
                ))
            })?;
        if sae != me.peer_sae {
            return Err(Refusal::bad(format!(
                "SAE_ID {:?} is unknown here: this KME shares keys between SAE {:?} and SAE {:?} \
                 only",
                brief(sae),
                me.sae,
                me.peer_sae
            )));
        }
        let method = request.method.as_str();
        match (operation, method) {
            ("status", "GET") => {
                no_query(query)?;
                let status = serde_json::to_vec(&self.status()?).expect("a status serialises");
                Ok((Zeroizing::new(status), Vec::new()))
            }
            ("enc_keys", "GET" | "POST") if self.side() == Side::Robot => Err(Refusal::bad(
                "this is the robot side's KME (the slave's): it gives keys only by the IDs the \
                 controller side gave, with dec_keys; enc_keys is the controller side's",
            )),
            ("dec_keys", "GET" | "POST") if self.side() == Side::Controller => Err(Refusal::bad(
                "this is the controller side's KME (the master's): it gives new keys with \
                 enc_keys; dec_keys is the robot side's",
            )),
            ("enc_keys", "GET") => {
                let (number, size) = number_and_size(&query_pairs(query, &["number", "size"])?)?;
                self.deliver(self.delivery.take_new(size, number as usize))
            }
            ("enc_keys", "POST") => {
                let asked: KeyRequest = parse_body(&request.body)?;
                if asked.additional_slaves.is_some_and(|ids| !ids.is_empty()) {
                    return Err(Refusal::bad(
                        "additional_slave_SAE_IDs: this KME shares keys with one slave SAE only \
                         (max_SAE_ID_count 0)",
                    ));
                }
                if asked.extension_mandatory.is_some_and(|e| !e.is_empty()) {
                    return Err(Refusal::bad(
                        "extension_mandatory: this KME supports no extension",
                    ));
                }
                let (number, size) = checked(asked.number, asked.size)?;
                self.deliver(self.delivery.take_new(size, number as usize))
            }
            ("dec_keys", "GET") => {
                let pairs = query_pairs(query, &["key_ID"])?;
                let ids: Vec<&str> = pairs.iter().map(|(_, value)| *value).collect();
                self.deliver_ids(&ids)
            }
            ("dec_keys", "POST") => {
                let asked: KeyIds = parse_body(&request.body)?;
                let ids: Vec<&str> = asked.key_ids.iter().map(|e| e.key_id.as_str()).collect();
                self.deliver_ids(&ids)
            }
            ("status" | "enc_keys" | "dec_keys", _) => Err(Refusal::bad(format!(
                "method {:?} is not allowed on {operation}: status takes GET, enc_keys and \
                 dec_keys take GET and POST",
                brief(method)
            ))),
            _ => Err(Refusal::bad(format!(
                "no such resource {:?}: the API is {PREFIX}{{SAE_ID}}/status, enc_keys or \
                 dec_keys",
                brief(path)
            ))),
        }
    }

    /// The `Status` of the keys shared with the peer SAE: counts of keys of the default
    /// size, now (`stored_key_count`) and once the pending final keys settle
    /// (`max_key_count`).
    fn status(&self) -> Result<Status<'_>, Refusal> {
        let me = &self.identity;
        let available = self
            .delivery
            .available(DEFAULT_SLICE_BITS)
            .map_err(|e| refusal(&e))?;
        let (master, slave) = match self.side() {
            Side::Controller => (&me.sae, &me.peer_sae),
            Side::Robot => (&me.peer_sae, &me.sae),
        };
        Ok(Status {
            source_kme: &me.kme,
            target_kme: &me.peer_kme,
            master_sae: master,
            slave_sae: slave,
            key_size: DEFAULT_SLICE_BITS,
            stored_key_count: available.settled,
            max_key_count: available.settled + available.pending,
            max_key_per_request: MAX_KEYS_PER_REQUEST,
            max_key_size: MAX_SLICE_BITS,
            min_key_size: MIN_SLICE_BITS,
            max_sae_id_count: 0,
        })
    }

    fn deliver_ids(&self, ids: &[&str]) -> Result<(Zeroizing<Vec<u8>>, Vec<Uuid>), Refusal> {
        if ids.is_empty() || ids.len() > MAX_KEYS_PER_REQUEST as usize {
            return Err(Refusal::bad(format!(
                "{} key_IDs: a request names 1 to {MAX_KEYS_PER_REQUEST}",
                ids.len()
            )));
        }
        self.deliver(self.delivery.take_by_id(ids))
    }

    /// The `Key container` of keys just taken, or the refusal of the take.
    fn deliver(
        &self,
        taken: Result<Vec<Delivered>, NetError>,
    ) -> Result<(Zeroizing<Vec<u8>>, Vec<Uuid>), Refusal> {
        let delivered = taken.map_err(|e| refusal(&e))?;
        let encoded: Vec<Zeroizing<String>> = delivered.iter().map(Delivered::base64).collect();
        let container = KeyContainer {
            keys: delivered
                .iter()
                .zip(&encoded)
                .map(|(d, key)| KeyEntry {
                    key_id: d.id.to_string(),
                    key: key.as_str(),
                })
                .collect(),
        };
        // Sized up front, so that no reallocation leaves a copy of the keys behind.
        let size = encoded.iter().map(|k| k.len() + 80).sum::<usize>() + 16;
        let mut body = Zeroizing::new(Vec::with_capacity(size));
        serde_json::to_writer(&mut *body, &container).expect("a key container serialises");
        Ok((body, delivered.iter().map(|d| d.id).collect()))
    }
}

/// A response with the standard's `Error` object: `{"message": …}`.
#[must_use]
pub fn error_response(status: u16, message: &str) -> Response {
    Response {
        status,
        body: Zeroizing::new(
            serde_json::to_vec(&ErrorBody { message }).expect("a message serialises"),
        ),
    }
}

/// The refusal of a failed take: 400 for the request's fault, 503 when no key can be given
/// now or the store failed (the body then says only that; the log has the error).
fn refusal(error: &NetError) -> Refusal {
    match error {
        NetError::Usage(message) => Refusal::bad(message.clone()),
        NetError::NoKey(message) | NetError::Pending(message) => Refusal(503, message.clone()),
        other => Refusal(
            503,
            format!("the key store failed; the KME's log names the file ({other})"),
        ),
    }
}

/// Refuses a query on a route that takes none.
fn no_query(query: &str) -> Result<(), Refusal> {
    if query.is_empty() {
        Ok(())
    } else {
        Err(Refusal::bad(format!(
            "status takes no query parameters, got {:?}",
            brief(query)
        )))
    }
}

/// The `name=value` pairs of `query`, each name one of `allowed` (no percent-encoding: the
/// values are numbers and UUIDs).
fn query_pairs<'q>(query: &'q str, allowed: &[&str]) -> Result<Vec<(&'q str, &'q str)>, Refusal> {
    query
        .split('&')
        .filter(|pair| !pair.is_empty())
        .map(|pair| {
            let (name, value) = pair.split_once('=').unwrap_or((pair, ""));
            if allowed.contains(&name) {
                Ok((name, value))
            } else {
                Err(Refusal::bad(format!(
                    "unknown query parameter {:?}: this call takes {}",
                    brief(name),
                    allowed.join(" and ")
                )))
            }
        })
        .collect()
}

/// `number` and `size` from query pairs, each at most once.
fn number_and_size(pairs: &[(&str, &str)]) -> Result<(u32, u32), Refusal> {
    let one = |name: &str| -> Result<Option<u64>, Refusal> {
        let mut values = pairs.iter().filter(|(n, _)| *n == name).map(|(_, v)| *v);
        let value = values.next();
        if values.next().is_some() {
            return Err(Refusal::bad(format!("{name} is given twice")));
        }
        value
            .map(|v| {
                v.parse::<u64>().map_err(|_| {
                    Refusal::bad(format!("{name}={:?} is not a whole number", brief(v)))
                })
            })
            .transpose()
    };
    checked(one("number")?, one("size")?)
}

/// `number` (default 1) and `size` (default [`DEFAULT_SLICE_BITS`]) within the status's
/// limits.
fn checked(number: Option<u64>, size: Option<u64>) -> Result<(u32, u32), Refusal> {
    let number = number.unwrap_or(1);
    if !(1..=u64::from(MAX_KEYS_PER_REQUEST)).contains(&number) {
        return Err(Refusal::bad(format!(
            "number {number}: a request asks for 1 to {MAX_KEYS_PER_REQUEST} keys \
             (max_key_per_request)"
        )));
    }
    let size = size.unwrap_or(u64::from(DEFAULT_SLICE_BITS));
    let size = u32::try_from(size).unwrap_or(u32::MAX);
    check_slice_bits(size).map_err(|e| Refusal::bad(format!("size: {e}")))?;
    Ok((number as u32, size))
}

/// A JSON body as `T`, refused with serde's message (which names the field) otherwise.
fn parse_body<T: serde::de::DeserializeOwned>(body: &[u8]) -> Result<T, Refusal> {
    serde_json::from_slice(body).map_err(|e| Refusal::bad(format!("the JSON body: {e}")))
}

/// `text` as a refusal quotes it: whole if short, else its start and its length.
fn brief(text: &str) -> String {
    const QUOTED: usize = 64;
    if text.chars().count() <= QUOTED {
        return text.to_owned();
    }
    let start: String = text.chars().take(QUOTED).collect();
    format!("{start}… ({} characters)", text.chars().count())
}

#[cfg(test)]
mod tests;
