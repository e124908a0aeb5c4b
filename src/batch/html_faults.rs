//! The page's table of injected faults: per batch and fault kind, how many struck, how many
//! the cell recovered from, and the parts they cost.

use std::fmt::Write as _;

use std::collections::BTreeMap;

use super::junit::xml_escape;
use crate::outcome::{FaultKind, FaultTally};

/// The faults table of the labelled batches `rows`, with its heading; empty when no fault
/// struck in any of them.
pub(super) fn faults_table(rows: &[(&str, &BTreeMap<FaultKind, FaultTally>)]) -> String {
    if rows.iter().all(|(_, faults)| faults.is_empty()) {
        return String::new();
    }
    let mut out = String::from(
        "<h2>Faults injected</h2>\n<table><tr><th>batch</th><th>fault</th><th>injected</th>\
         <th>recovered</th><th>share</th><th>parts lost</th></tr>\n",
    );
    for (label, faults) in rows {
        for (kind, tally) in *faults {
            let share = tally
                .recovered_share()
                .map_or("-".to_owned(), |s| format!("{s:.3}"));
            let _ = writeln!(
                out,
                "<tr><td>{}</td><td>{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td>\
                 <td class=\"n\">{share}</td><td class=\"n\">{}</td></tr>",
                xml_escape(label),
                kind.as_str(),
                tally.injected,
                tally.recovered,
                tally.lost,
            );
        }
    }
    out.push_str("</table>\n");
    out
}
