//! The key server's TLS (rustls, TLS 1.2 and 1.3 with the `ring` provider): its certificate
//! chain and private key, and mutual authentication — a client must present a certificate
//! that chains to the client CA, or the handshake fails; its subject's common name then names
//! the SAE it is ([`common_name`]). The private key file is refused, like a pairing file, if
//! another user owns it or group or others may read or write it.

use std::io::Read as _;
use std::path::Path;
use std::sync::Arc;

use rustls::RootCertStore;
use rustls::pki_types::pem::PemObject as _;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use rustls::server::WebPkiClientVerifier;
use x509_cert::der::{Decode as _, Tagged as _, asn1};
use zeroize::Zeroizing;

use crate::error::NetError;
use crate::owned_file::{self, ANY_ACCESS_BY_OTHERS};

/// The files of the server's TLS.
#[derive(Clone, Copy, Debug)]
pub struct TlsFiles<'a> {
    /// The server's certificate chain (PEM), its own certificate first.
    pub cert: &'a Path,
    /// The server's private key (PEM: PKCS#8, PKCS#1 or SEC1).
    pub key: &'a Path,
    /// The CA whose certificates clients must present (PEM; one or more).
    pub client_ca: &'a Path,
}

/// The server configuration: the certificate, the key, client certificates required and
/// verified against the client CA.
///
/// # Errors
/// A file is missing, unreadable or holds no such PEM item; the key file is open to others;
/// the key does not match the certificate (each names the file).
pub fn server_config(files: TlsFiles<'_>) -> Result<Arc<rustls::ServerConfig>, NetError> {
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let chain = certificates(files.cert, "--tls-cert")?;
    let mut roots = RootCertStore::empty();
    for ca in certificates(files.client_ca, "--client-ca")? {
        roots.add(ca).map_err(|e| {
            NetError::Usage(format!(
                "--client-ca {}: not a CA certificate rustls can use: {e}",
                files.client_ca.display()
            ))
        })?;
    }
    let verifier = WebPkiClientVerifier::builder_with_provider(Arc::new(roots), provider.clone())
        .build()
        .map_err(|e| NetError::Usage(format!("--client-ca {}: {e}", files.client_ca.display())))?;
    let config = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| NetError::Usage(format!("TLS: {e}")))?
        .with_client_cert_verifier(verifier)
        .with_single_cert(chain, private_key(files.key)?)
        .map_err(|e| {
            NetError::Usage(format!(
                "--tls-key {} does not go with --tls-cert {}: {e}",
                files.key.display(),
                files.cert.display()
            ))
        })?;
    Ok(Arc::new(config))
}

/// The subject common name of a DER certificate, if it has exactly one (UTF-8, printable or
/// IA5 string).
#[must_use]
pub fn common_name(certificate: &[u8]) -> Option<String> {
    const CN: x509_cert::der::oid::ObjectIdentifier =
        x509_cert::der::oid::ObjectIdentifier::new_unwrap("2.5.4.3");
    let certificate = x509_cert::Certificate::from_der(certificate).ok()?;
    let mut names = certificate
        .tbs_certificate
        .subject
        .0
        .iter()
        .flat_map(|rdn| rdn.0.iter())
        .filter(|attribute| attribute.oid == CN)
        .map(|attribute| {
            let value = &attribute.value;
            match value.tag() {
                x509_cert::der::Tag::Utf8String => value
                    .decode_as::<asn1::Utf8StringRef<'_>>()
                    .ok()
                    .map(|s| s.as_str().to_owned()),
                x509_cert::der::Tag::PrintableString => value
                    .decode_as::<asn1::PrintableStringRef<'_>>()
                    .ok()
                    .map(|s| s.as_str().to_owned()),
                x509_cert::der::Tag::Ia5String => value
                    .decode_as::<asn1::Ia5StringRef<'_>>()
                    .ok()
                    .map(|s| s.as_str().to_owned()),
                _ => None,
            }
        });
    let name = names.next()??;
    names.next().is_none().then_some(name)
}

/// Every certificate in the PEM file `path` (at least one).
fn certificates(path: &Path, flag: &str) -> Result<Vec<CertificateDer<'static>>, NetError> {
    let bad = |message: String| NetError::Usage(format!("{flag} {}: {message}", path.display()));
    let text = std::fs::read(path).map_err(|e| bad(format!("cannot be read: {e}")))?;
    let chain = CertificateDer::pem_slice_iter(&text)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| bad(format!("is not PEM: {e}")))?;
    if chain.is_empty() {
        return Err(bad("holds no CERTIFICATE".into()));
    }
    Ok(chain)
}

/// The private key in the PEM file `path` (a link is followed, as certificate tools lay
/// them out), which only this user may access.
fn private_key(path: &Path) -> Result<PrivateKeyDer<'static>, NetError> {
    let bad = |message: String| NetError::Usage(format!("--tls-key {}: {message}", path.display()));
    let mut file = std::fs::File::open(path).map_err(|e| bad(format!("cannot be opened: {e}")))?;
    owned_file::check_file(&file, path, "--tls-key", ANY_ACCESS_BY_OTHERS)?;
    let mut text = Zeroizing::new(Vec::new());
    file.read_to_end(&mut text)
        .map_err(|e| bad(format!("cannot be read: {e}")))?;
    PrivateKeyDer::from_pem_slice(&text).map_err(|e| bad(format!("holds no private key: {e}")))
}
