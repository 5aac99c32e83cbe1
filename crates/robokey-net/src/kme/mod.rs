//! `robokey kme`: an ETSI GS QKD 014 v1.1.1 key-delivery server on one agent's store
//! (docs/keys.md). HTTPS with mutual TLS ([`tls`]), bounded HTTP/1.1 ([`http`]), the
//! standard's routes, JSON and status codes ([`api`]), and the listener that serves them
//! ([`server`]). It reads the store its agent writes, beside the running agent: it never
//! writes the journal, and takes keys under the key folder's lock like every other change
//! to `keys/` (crate::key_store).

pub mod api;
pub mod http;
pub mod server;
pub mod tls;
