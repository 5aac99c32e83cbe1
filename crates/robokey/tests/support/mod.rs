//! Helpers shared by the lockstep tests.

use robokey::protocol::{Message, PostFragment};

/// A post-processing fragment: traffic of another protocol on the same channel, which session
/// endpoints must ignore.
pub fn post_fragment() -> Message {
    Message::Post(PostFragment {
        message: 1,
        index: 0,
        count: 1,
        bytes: vec![1; 9],
    })
}
