//! How a name from a device, a standard or a state machine is spelled where the project gives
//! it as one word (a key, a field, a ROS parameter): [`snake_case`]. One function for every
//! such name, so that a state, a mode and a PDO entry are spelled by the same rule wherever
//! they show.

/// `name` in snake case: ASCII letters and digits kept and lowered, a word boundary made an
/// underscore — any other character (a space, a dot, a dash, a letter outside ASCII), a lower
/// case letter or digit followed by a capital, and the last capital of an acronym followed by a
/// lower case letter — never two underscores in a row, none at either end. "Operation enabled"
/// is "operation_enabled", "SafeOp" "safe_op", "TxPDO-Map Channel 1" "tx_pdo_map_channel_1",
/// "AIN.VALUE" "ain_value"; a name with no ASCII letter or digit is empty.
pub fn snake_case(name: &str) -> String {
    let chars: Vec<char> = name.chars().collect();
    let mut out = String::with_capacity(name.len() + 4);
    let mut boundary = false;
    for (i, &c) in chars.iter().enumerate() {
        if !c.is_ascii_alphanumeric() {
            boundary = true;
            continue;
        }
        let previous = i.checked_sub(1).map(|p| chars[p]);
        let next = chars.get(i + 1).copied();
        if c.is_ascii_uppercase() {
            let after_lower = previous.is_some_and(|p| p.is_ascii_lowercase() || p.is_ascii_digit());
            let ends_acronym =
                previous.is_some_and(|p| p.is_ascii_uppercase()) && next.is_some_and(|n| n.is_ascii_lowercase());
            boundary |= after_lower || ends_acronym;
        }
        if boundary && !out.is_empty() {
            out.push('_');
        }
        boundary = false;
        out.push(c.to_ascii_lowercase());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::snake_case;

    #[test]
    fn names_of_states_modes_and_pdo_entries() {
        for (name, snake) in [
            ("Operation enabled", "operation_enabled"),
            ("Not ready to switch on", "not_ready_to_switch_on"),
            ("SafeOp", "safe_op"),
            ("PreOp", "pre_op"),
            ("Init", "init"),
            ("profile position", "profile_position"),
            ("TxPDO-Map Channel 1", "tx_pdo_map_channel_1"),
            ("AIN.VALUE", "ain_value"),
            ("Channel 1", "channel_1"),
            ("Input", "input"),
            ("  Status__word ", "status_word"),
            ("Eingänge", "eing_nge"),
            ("Ch1Value", "ch1_value"),
            ("", ""),
            ("---", ""),
        ] {
            assert_eq!(snake_case(name), snake, "{name:?}");
        }
    }

    #[test]
    fn a_snake_name_is_its_own_snake_case() {
        for name in ["operation_enabled", "safe_op", "channel_1_input", "x"] {
            assert_eq!(snake_case(name), name);
        }
    }
}
