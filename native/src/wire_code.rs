//! Sets of wire codes, declared in one shape: each code with its value and its name as the
//! standard spells it; and enums that are no wire code but carry a text per variant, declared
//! the same way so that no variant is listed twice.
//!
//! - A closed set (`enum Name: raw, "what" { Variant = value => "name", ... }`) is a `#[repr]`
//!   enum with its names, `ALL`, `TryFrom` of the raw value (an error naming the value and the
//!   set) and the raw value back.
//! - An open set (`struct Name(raw) { CONST = value => "name", value => "name", ... } else {
//!   pattern => "name", ... }`), where a slave may send codes outside the standard's list (a
//!   vendor's), is a newtype over the wire value: the codes this crate uses by name as
//!   constants, a `name()` for every code of the list and the `else` patterns for the rest.
//! - In both, a code's documentation ends with its value and name, so a code whose name says
//!   all there is to say needs no doc comment of its own.
//! - An enum of names (`named_variants!`: `enum Name { Variant => "text", ... } fn name;`),
//!   optionally with discriminants (`Variant = value => "text"`), is the enum with `ALL` and
//!   the text of each variant by the method the declaration names (`name`, `describe`, ...,
//!   documented there): for a set the crate spells (a link spec's option values, a DS402 state)
//!   but receives from no wire.

use std::fmt;

/// Declares a closed set of wire codes; see the module documentation.
macro_rules! wire_codes {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident: $raw:ty, $what:literal {
            $($(#[$variant_meta:meta])* $variant:ident = $value:literal => $text:literal,)+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        #[repr($raw)]
        $vis enum $name {
            $($(#[$variant_meta])* #[doc = concat!("`", stringify!($value), "`: ", $text, ".")] $variant = $value,)+
        }

        impl $name {
            /// Every code of the set, in the standard's order.
            pub const ALL: [$name; [$(stringify!($variant)),+].len()] = [$($name::$variant),+];

            /// The code's name as the standard spells it.
            pub fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $text,)+
                }
            }
        }

        impl TryFrom<$raw> for $name {
            type Error = crate::wire_code::UnknownCode;

            fn try_from(value: $raw) -> Result<Self, crate::wire_code::UnknownCode> {
                match value {
                    $($value => Ok($name::$variant),)+
                    _ => Err(crate::wire_code::UnknownCode {
                        what: $what,
                        value: value.into(),
                        known: &[$(($value, $text)),+],
                    }),
                }
            }
        }

        impl From<$name> for $raw {
            fn from(code: $name) -> $raw {
                code as $raw
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{} ({})", *self as $raw, self.name())
            }
        }
    };
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident($raw:ty) {
            $($($(#[$const_meta:meta])* $constant:ident =)? $value:literal => $text:literal,)+
        } else {
            $($other:pat => $other_text:literal,)+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        $vis struct $name(pub $raw);

        impl $name {
            $($(
                $(#[$const_meta])*
                #[doc = concat!("`", stringify!($value), "`: ", $text, ".")]
                pub const $constant: $name = $name($value);
            )?)+

            /// The code's name as the standard spells it, for any code.
            pub fn name(self) -> &'static str {
                match self.0 {
                    $($value => $text,)+
                    $($other => $other_text,)+
                }
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "0x{:0width$X} ({})", self.0, self.name(), width = 2 * std::mem::size_of::<$raw>())
            }
        }
    };
}

/// Declares an enum with a text per variant and `ALL`; see the module documentation.
macro_rules! named_variants {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident {
            $($(#[$variant_meta:meta])* $variant:ident $(= $value:literal)? => $text:literal,)+
        }
        $(#[$text_meta:meta])*
        fn $text_fn:ident;
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        $vis enum $name {
            $($(#[$variant_meta])* $variant $(= $value)?,)+
        }

        impl $name {
            /// Every variant, in the order declared.
            pub const ALL: [$name; [$(stringify!($variant)),+].len()] = [$($name::$variant),+];

            $(#[$text_meta])*
            pub fn $text_fn(self) -> &'static str {
                match self {
                    $($name::$variant => $text,)+
                }
            }
        }
    };
}

/// A wire code outside its closed set (a CoE service, an SDO information opcode, ...).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownCode {
    /// The field the code came in, e.g. "CoE service".
    pub what: &'static str,
    /// The value received (an `i32`, which holds the value of every set: `u8`, `u16`, `i8`).
    pub value: i32,
    /// The set's codes and names, to say what was allowed.
    pub known: &'static [(i32, &'static str)],
}

impl fmt::Display for UnknownCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {} is none of", self.what, self.value)?;
        for (i, (value, name)) in self.known.iter().enumerate() {
            write!(f, "{} {value} ({name})", if i == 0 { "" } else { "," })?;
        }
        Ok(())
    }
}

impl std::error::Error for UnknownCode {}
