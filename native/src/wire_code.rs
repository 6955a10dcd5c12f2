//! Closed sets of wire codes as enums: one declaration gives the `#[repr]` enum, its names as
//! the standard spells them, `TryFrom` of the raw value (an error naming the value and the
//! set) and the raw value back.

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
            $($(#[$variant_meta])* $variant = $value,)+
        }

        impl $name {
            /// Every code of the set, in the standard's order.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];

            /// The code's name as the standard spells it.
            pub fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $text,)+
                }
            }
        }

        impl TryFrom<$raw> for $name {
            type Error = crate::error::UnknownCode;

            fn try_from(value: $raw) -> Result<Self, crate::error::UnknownCode> {
                match value {
                    $($value => Ok($name::$variant),)+
                    _ => Err(crate::error::UnknownCode {
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
}
