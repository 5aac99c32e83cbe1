//! A localhost-only ROS 2 participant, topics with their QoS, and a listener thread that
//! keeps the latest message of a subscription with the instant it arrived.

use std::collections::VecDeque;
use std::net::Ipv4Addr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::{Context, Name, Node, NodeName, NodeOptions, QosProfile, Subscription};
use serde::de::DeserializeOwned;

use super::msg::{Kind, type_name};
use crate::error::NetError;

/// Highest DDS domain id whose ports fit (RTPS port mapping with the default gains).
pub const MAX_DOMAIN_ID: u16 = 232;

/// Delivery of a topic (ROS 2's reliability QoS).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delivery {
    /// Lost samples are resent (ROS 2's default). A reliable subscription does not match a
    /// best-effort publisher.
    Reliable,
    /// Samples may be lost (ROS 2's sensor-data profile). A best-effort subscription
    /// matches either kind of publisher.
    BestEffort,
}

/// A topic's name and QoS.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopicSpec {
    /// Absolute ROS name, e.g. `/cmd_vel`.
    pub name: String,
    /// Reliability.
    pub delivery: Delivery,
    /// History depth (keep last).
    pub depth: usize,
}

impl TopicSpec {
    /// The ROS 2 QoS profile: volatile, keep last `depth`, this reliability.
    #[must_use]
    pub fn qos(&self) -> QosProfile {
        let reliability = match self.delivery {
            Delivery::Reliable => Reliability::Reliable {
                when_full: WhenFull::Wait(Duration::from_millis(100)),
            },
            Delivery::BestEffort => Reliability::BestEffort,
        };
        QosProfile::subscription_default()
            .reliability(reliability)
            .durability(Durability::Volatile)
            .history(History::KeepLast {
                depth: self.depth.max(1),
            })
    }

    /// The parsed ROS name.
    ///
    /// # Errors
    /// Not an absolute ROS topic name.
    pub fn ros_name(&self) -> Result<Name, NetError> {
        if !self.name.starts_with('/') {
            return Err(NetError::Usage(format!(
                "topic {:?}: give an absolute ROS name, starting with /",
                self.name
            )));
        }
        Name::parse(&self.name)
            .map_err(|e| NetError::Usage(format!("topic {:?}: not a ROS name: {e:?}", self.name)))
    }
}

/// The two topics of a differential-drive robot and how they are carried.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RobotTopics {
    /// DDS domain (ROS_DOMAIN_ID), 0 to [`MAX_DOMAIN_ID`].
    pub domain_id: u16,
    /// Velocity commands (`geometry_msgs/Twist` or `TwistStamped`).
    pub cmd_vel: TopicSpec,
    /// Whether `cmd_vel` carries `TwistStamped` (Jazzy's TurtleBot3) instead of `Twist`.
    pub stamped: bool,
    /// Odometry (`nav_msgs/Odometry`).
    pub odom: TopicSpec,
}

impl RobotTopics {
    /// `/cmd_vel` (reliable, Twist) and `/odom` (best effort, so that it matches any
    /// publisher), depth 10, domain 0.
    #[must_use]
    pub fn turtlebot3() -> Self {
        Self {
            domain_id: 0,
            cmd_vel: TopicSpec {
                name: "/cmd_vel".into(),
                delivery: Delivery::Reliable,
                depth: 10,
            },
            stamped: false,
            odom: TopicSpec {
                name: "/odom".into(),
                delivery: Delivery::BestEffort,
                depth: 10,
            },
        }
    }

    /// The command message type.
    #[must_use]
    pub fn cmd_kind(&self) -> Kind {
        if self.stamped {
            Kind::TwistStamped
        } else {
            Kind::Twist
        }
    }
}

/// A node on a DDS participant restricted to the loopback interface
/// (`DomainParticipantBuilder::with_only_networks([127.0.0.1])`): it joins multicast and
/// advertises locators only on `lo`, and finds same-host peers by unicast SPDP to
/// 127.0.0.1. Its unicast sockets still bind 0.0.0.0 (RustDDS 0.15: "not a hard
/// transport-level ACL"), so a host firewall is what keeps other hosts' datagrams out
/// (docs/ros2.md).
///
/// # Errors
/// The participant or node cannot be created (no free participant id, a bad name).
pub fn localhost_node(name: &str, domain_id: u16) -> Result<(Context, Node), NetError> {
    if domain_id > MAX_DOMAIN_ID {
        return Err(NetError::Usage(format!(
            "ROS domain {domain_id} is not allowed (allowed: 0 to {MAX_DOMAIN_ID})"
        )));
    }
    let participant = DomainParticipantBuilder::new(domain_id)
        .with_only_networks([Ipv4Addr::LOCALHOST])
        .build()
        .map_err(|e| NetError::Ros2(format!("create the DDS participant: {e:?}")))?;
    let context = Context::from_domain_participant(participant)
        .map_err(|e| NetError::Ros2(format!("create the ROS 2 context: {e:?}")))?;
    let node_name = NodeName::new("/robokey", name)
        .map_err(|e| NetError::Ros2(format!("node name {name:?}: {e:?}")))?;
    let node = context
        .new_node(
            node_name,
            NodeOptions::new()
                .enable_rosout(false)
                .start_parameter_services(false),
        )
        .map_err(|e| NetError::Ros2(format!("create the ROS 2 node {name}: {e:?}")))?;
    Ok((context, node))
}

/// Creates the topic `spec` of message type `kind` on `node`.
///
/// # Errors
/// A bad name, or DDS refuses the topic.
pub fn topic(
    node: &Node,
    spec: &TopicSpec,
    kind: Kind,
) -> Result<ros2_client::dds::rustdds::Topic, NetError> {
    node.create_topic(&spec.ros_name()?, type_name(kind), &spec.qos())
        .map_err(|e| NetError::Ros2(format!("create topic {}: {e:?}", spec.name)))
}

/// A message as the listener keeps it.
#[derive(Clone, Debug, PartialEq)]
pub struct Arrival<V> {
    /// The message, mapped.
    pub value: V,
    /// When the listener took it from DDS (within a millisecond of its arrival).
    pub at: Instant,
    /// How many valid messages had arrived, this one included.
    pub number: u64,
}

#[derive(Debug)]
struct State<V> {
    latest: Option<Arrival<V>>,
    queue: VecDeque<Arrival<V>>,
    rejected: u64,
    last_rejection: Option<String>,
    failed: Option<String>,
}

/// Most messages taken per wake-up of a listener (a reader that keeps reporting errors
/// cannot hold the thread).
const MAX_TAKES_PER_WAKE: usize = 256;
/// How often a listener looks at its stop flag while no message arrives.
const LISTENER_TICK: Duration = Duration::from_millis(20);

/// A thread that takes every message of a subscription as it arrives, maps it (an
/// invalid one is counted and dropped), keeps the latest with its arrival instant and,
/// if asked, a bounded queue of the unread ones. Stops when dropped.
pub struct Listener<V> {
    topic: String,
    shared: Arc<(Mutex<State<V>>, Condvar)>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl<V: Clone + Send + 'static> Listener<V> {
    /// Starts listening on `subscription` (of topic `topic`), mapping each message with
    /// `map`. With `queue > 0` the last `queue` unread messages are kept for [`Self::drain`].
    ///
    /// # Errors
    /// The thread or its poller cannot be started.
    pub fn spawn<M, F>(
        mut subscription: Subscription<M>,
        topic: &str,
        queue: usize,
        mut map: F,
    ) -> Result<Self, NetError>
    where
        M: DeserializeOwned + Send + 'static,
        F: FnMut(M) -> Result<V, String> + Send + 'static,
    {
        let mut poll = Poll::new().map_err(NetError::io(format!("poll {topic}")))?;
        poll.registry()
            .register(&mut subscription, Token(0), Interest::READABLE)
            .map_err(NetError::io(format!("poll {topic}")))?;
        let shared = Arc::new((
            Mutex::new(State {
                latest: None,
                queue: VecDeque::with_capacity(queue),
                rejected: 0,
                last_rejection: None,
                failed: None,
            }),
            Condvar::new(),
        ));
        let stop = Arc::new(AtomicBool::new(false));
        let (thread_shared, thread_stop) = (Arc::clone(&shared), Arc::clone(&stop));
        let name = topic.to_owned();
        let thread = std::thread::Builder::new()
            .name(format!("ros2 {topic}"))
            .spawn(move || {
                let mut events = Events::with_capacity(8);
                let mut number = 0u64;
                while !thread_stop.load(Ordering::Relaxed) {
                    if let Err(e) = poll.poll(&mut events, Some(LISTENER_TICK))
                        && e.kind() != std::io::ErrorKind::Interrupted
                    {
                        let mut state = lock(&thread_shared.0);
                        state.failed = Some(format!("poll {name}: {e}"));
                        thread_shared.1.notify_all();
                        return;
                    }
                    for _ in 0..MAX_TAKES_PER_WAKE {
                        let taken = subscription.take();
                        let at = Instant::now();
                        let mapped = match taken {
                            Ok(None) => break,
                            Ok(Some((message, _info))) => map(message),
                            Err(e) => Err(format!("undecodable message: {e:?}")),
                        };
                        let mut state = lock(&thread_shared.0);
                        match mapped {
                            Ok(value) => {
                                number += 1;
                                let arrival = Arrival { value, at, number };
                                if queue > 0 {
                                    if state.queue.len() == queue {
                                        state.queue.pop_front();
                                    }
                                    state.queue.push_back(arrival.clone());
                                }
                                state.latest = Some(arrival);
                            }
                            Err(why) => {
                                state.rejected += 1;
                                state.last_rejection = Some(why);
                            }
                        }
                        thread_shared.1.notify_all();
                    }
                }
            })
            .map_err(NetError::io(format!("start the {topic} listener")))?;
        Ok(Self {
            topic: topic.to_owned(),
            shared,
            stop,
            thread: Some(thread),
        })
    }

    /// The latest valid message, if any arrived.
    #[must_use]
    pub fn latest(&self) -> Option<Arrival<V>> {
        lock(&self.shared.0).latest.clone()
    }

    /// Takes the queued messages (oldest first).
    #[must_use]
    pub fn drain(&self) -> Vec<Arrival<V>> {
        lock(&self.shared.0).queue.drain(..).collect()
    }

    /// Waits until the latest message satisfies `ready` (or one is queued, with
    /// `queued`), at most until `deadline`. Returns whether it did.
    ///
    /// # Errors
    /// The listener thread failed.
    pub fn wait(
        &self,
        deadline: Instant,
        queued: bool,
        ready: impl Fn(&Arrival<V>) -> bool,
    ) -> Result<bool, NetError> {
        let (mutex, condvar) = &*self.shared;
        let mut state = lock(mutex);
        loop {
            if let Some(failed) = &state.failed {
                return Err(NetError::Ros2(failed.clone()));
            }
            if (queued && !state.queue.is_empty()) || state.latest.as_ref().is_some_and(&ready) {
                return Ok(true);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(false);
            }
            state = condvar
                .wait_timeout(state, left)
                .map_or_else(|e| e.into_inner().0, |(guard, _)| guard);
        }
    }

    /// Waits up to `timeout` for the first valid message, a `kind` published on this
    /// listener's topic, to which it subscribed with `delivery` (set by the flag `qos_flag`).
    ///
    /// # Errors
    /// None came: a named error saying what was found on the graph (no publisher,
    /// publishers of another type, or only best-effort publishers for a reliable
    /// subscription), how many messages were invalid and why, then `hint`.
    pub fn wait_for_first(
        &self,
        context: &Context,
        kind: Kind,
        (delivery, qos_flag): (Delivery, &str),
        timeout: Duration,
        hint: &str,
    ) -> Result<(), NetError> {
        if self.wait(Instant::now() + timeout, false, |_| true)? {
            return Ok(());
        }
        let waited = format!(
            "no valid {} within {:.1} s",
            self.topic,
            timeout.as_secs_f64()
        );
        let why = match wait_for_peer(context, &self.topic, kind, Peer::Publisher, Instant::now()) {
            Err(why) => format!(" ({why})"),
            Ok(()) => {
                if let Some(mismatch) =
                    reliability_mismatch(context, &self.topic, kind, Peer::Publisher, delivery)
                {
                    return Err(NetError::Ros2(format!(
                        "{waited}: {mismatch}: subscribe best effort ({qos_flag} best-effort)"
                    )));
                }
                String::new()
            }
        };
        Err(NetError::Ros2(format!(
            "{waited}{why}{}: {hint}",
            self.rejections()
        )))
    }

    /// `", N rejected (last: why)"` when messages were rejected, else empty.
    #[must_use]
    pub fn rejections(&self) -> String {
        let state = lock(&self.shared.0);
        match (&state.last_rejection, state.rejected) {
            (Some(why), n) => format!("; {n} invalid {} messages (last: {why})", self.topic),
            (None, _) => String::new(),
        }
    }
}

impl<V> Drop for Listener<V> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Locks, ignoring poisoning (the state is plain data, valid at every point).
fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Which side of a topic another participant is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Peer {
    /// A subscriber (a reader).
    Subscriber,
    /// A publisher (a writer).
    Publisher,
}

/// One of the other participants' readers or writers of a topic, as discovered.
struct Endpoint {
    /// Its DDS type name.
    type_name: String,
    /// Whether it is best effort (else reliable).
    best_effort: bool,
}

/// The other participants' `peer`s of ROS topic `topic`. A reliability left out of the
/// discovery data is DDS's default: reliable for a writer, best effort for a reader.
fn peer_endpoints(context: &Context, topic: &str, peer: Peer) -> Vec<Endpoint> {
    use ros2_client::dds::rustdds::policy::Reliability as Given;
    let dds_name = format!("rt/{}", topic.trim_start_matches('/'));
    let participant = context.domain_participant();
    let best_effort = |given: Option<Given>, default: bool| {
        given.map_or(default, |given| matches!(given, Given::BestEffort))
    };
    match peer {
        Peer::Subscriber => participant
            .discovered_readers()
            .iter()
            .map(|r| &r.subscription_topic_data)
            .filter(|t| *t.topic_name() == dds_name)
            .map(|t| Endpoint {
                type_name: t.type_name().clone(),
                best_effort: best_effort(t.qos().reliability(), true),
            })
            .collect(),
        Peer::Publisher => participant
            .discovered_writers()
            .iter()
            .map(|w| &w.publication_topic_data)
            .filter(|t| t.topic_name == dds_name)
            .map(|t| Endpoint {
                type_name: t.type_name.clone(),
                best_effort: best_effort(t.reliability, false),
            })
            .collect(),
    }
}

/// The DDS type names of the other participants' `peer`s of ROS topic `topic`.
fn peer_types(context: &Context, topic: &str, peer: Peer) -> Vec<String> {
    peer_endpoints(context, topic, peer)
        .into_iter()
        .map(|e| e.type_name)
        .collect()
}

/// When every discovered `peer` of `topic` with message type `kind` has a reliability DDS
/// does not match with `ours` — it never delivers from a best-effort writer to a reliable
/// reader —, the sentence that says so; `None` when one matches or none is there.
pub fn reliability_mismatch(
    context: &Context,
    topic: &str,
    kind: Kind,
    peer: Peer,
    ours: Delivery,
) -> Option<String> {
    let wanted = type_name(kind).dds_msg_type();
    let ours_best_effort = ours == Delivery::BestEffort;
    let theirs: Vec<bool> = peer_endpoints(context, topic, peer)
        .into_iter()
        .filter(|e| e.type_name == wanted)
        .map(|e| e.best_effort)
        .collect();
    let delivered = |theirs_best_effort: bool| match peer {
        Peer::Publisher => !theirs_best_effort || ours_best_effort,
        Peer::Subscriber => !ours_best_effort || theirs_best_effort,
    };
    if theirs.is_empty() || theirs.into_iter().any(delivered) {
        return None;
    }
    Some(match peer {
        Peer::Publisher => format!(
            "a QoS reliability mismatch: the publishers of {topic} are best effort and this \
             subscription is reliable, and DDS never delivers from a best-effort writer to a \
             reliable reader"
        ),
        Peer::Subscriber => format!(
            "a QoS reliability mismatch: the subscribers of {topic} are reliable and this \
             publisher is best effort, and DDS never delivers from a best-effort writer to a \
             reliable reader"
        ),
    })
}

/// Waits until another participant's `peer` of `topic` with message type `kind` is
/// discovered, at most until `deadline`, looking every 20 ms.
///
/// # Errors
/// None by then: what was found instead (peers of another type, or none), as a sentence.
pub fn wait_for_peer(
    context: &Context,
    topic: &str,
    kind: Kind,
    peer: Peer,
    deadline: Instant,
) -> Result<(), String> {
    let wanted = type_name(kind).dds_msg_type();
    loop {
        let found = peer_types(context, topic, peer);
        if found.contains(&wanted) {
            return Ok(());
        }
        if Instant::now() >= deadline {
            let what = match peer {
                Peer::Subscriber => "subscriber",
                Peer::Publisher => "publisher",
            };
            return Err(if found.is_empty() {
                format!("no {what} of {topic}")
            } else {
                let mut found = found;
                found.dedup();
                format!(
                    "the {what}s of {topic} use {}, not {wanted}",
                    found.join(", ")
                )
            });
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}
