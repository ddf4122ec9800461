//! Identification experiments of `softcbf run --experiment`: the feed-forward tensions of
//! each tick (static tension sets held to rest, multisine excitation), under the filter.
