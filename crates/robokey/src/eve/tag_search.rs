//! The key tag as a key oracle (the `transcript` strategy, docs/threat-model.md): in the simulator the tag's MAC keys are public
//! (the worst case of a pairing secret that leaks), so Eve can test candidate keys against
//! it. She flips her least reliable codewords to their runner-up messages, fewest flips
//! first.

use crate::code::SoftDecoded;
use crate::protocol::{Confirmer, Direction, FateLedger, KeyBits, TAG_BYTES};

/// What a search found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TagMatch {
    /// The message of every codeword (only accepted ones are verified).
    pub messages: Vec<u64>,
    /// Codewords flipped from her first guess.
    pub flips: u32,
    /// Tags computed.
    pub tries: u64,
}

/// Whether `tag` is the key tag of `key`, sent in either direction (a tag on the wire does
/// not say who sent it).
#[must_use]
pub fn is_key_tag(confirmer: &Confirmer, key: &[u8], tag: &[u8; TAG_BYTES]) -> bool {
    [Direction::ToRobot, Direction::ToController]
        .into_iter()
        .any(|direction| confirmer.key_tag(direction, key) == *tag)
}

/// Searches the candidates that differ from `decoded` in at most `max_flips` of the
/// accepted codewords, the least reliable ones (smallest margin), for the key whose tag is
/// `tag`. At most `2^max_flips` tags are computed.
#[must_use]
pub fn search_key(
    confirmer: &Confirmer,
    k: usize,
    fates: &FateLedger,
    decoded: &[SoftDecoded],
    tag: &[u8; TAG_BYTES],
    max_flips: u32,
) -> Option<TagMatch> {
    let mut suspects: Vec<usize> = (0..decoded.len())
        .filter(|&i| fates.get(i as u32) == Some(true))
        .collect();
    suspects.sort_by(|&a, &b| decoded[a].margin.total_cmp(&decoded[b].margin));
    suspects.truncate(max_flips as usize);
    let mut messages: Vec<u64> = decoded.iter().map(|d| d.message).collect();
    let mut tries = 0;
    let mut test = |messages: &[u64]| {
        tries += 1;
        let key: KeyBits = fates.accepted_key(messages, k);
        is_key_tag(confirmer, &key, tag)
    };
    for flips in 0..=suspects.len() as u32 {
        // Gosper's hack: every subset of `flips` suspects, in increasing bit order.
        let mut subset: u64 = (1u64 << flips) - 1;
        while subset < 1u64 << suspects.len() {
            for (bit, &i) in suspects.iter().enumerate() {
                messages[i] = if subset >> bit & 1 == 1 {
                    decoded[i].runner_up
                } else {
                    decoded[i].message
                };
            }
            if test(&messages) {
                return Some(TagMatch {
                    messages,
                    flips,
                    tries,
                });
            }
            if subset == 0 {
                break;
            }
            let lowest = subset & subset.wrapping_neg();
            let ripple = subset + lowest;
            subset = (((ripple ^ subset) >> 2) / lowest) | ripple;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::protocol::SessionPlan;

    #[test]
    fn finds_the_key_behind_a_tag_by_flipping_unreliable_codewords() {
        let plan = SessionPlan::from_config(&Config::default(), 3);
        let codewords = 40;
        let mut fates = FateLedger::new(codewords);
        for i in 0..codewords {
            fates.record(i, i % 5 != 0);
        }
        let truth: Vec<u64> = (0..u64::from(codewords)).map(|i| i * 7 % 3 % 2).collect();
        let confirmer = &plan.agreed.confirmer;
        let tag = confirmer.key_tag(Direction::ToRobot, &fates.accepted_key(&truth, 1));
        // Her guess is wrong on codewords 3 and 11 (weak) and right elsewhere; codeword 0 is
        // weakest but rejected, so it must not use up a flip.
        let decoded: Vec<SoftDecoded> = truth
            .iter()
            .enumerate()
            .map(|(i, &m)| {
                let wrong = i == 3 || i == 11;
                SoftDecoded {
                    message: if wrong { m ^ 1 } else { m },
                    runner_up: if wrong { m } else { m ^ 1 },
                    margin: match i {
                        0 => 0.0,
                        3 => 0.2,
                        11 => 0.1,
                        _ => 1.0 + i as f64,
                    },
                }
            })
            .collect();
        let found = search_key(confirmer, 1, &fates, &decoded, &tag, 4).expect("within 4 flips");
        assert_eq!(found.flips, 2);
        assert_eq!(
            fates.accepted_key(&found.messages, 1),
            fates.accepted_key(&truth, 1)
        );
        // No flip, 4 single flips, then {11, 3}, the two weakest: the first pair tried.
        assert_eq!(found.tries, 1 + 4 + 1);
        assert_eq!(search_key(confirmer, 1, &fates, &decoded, &tag, 1), None);
    }
}
