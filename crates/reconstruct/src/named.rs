//! Option enums with stable command-line names.
//!
//! Every option of every estimator is an enum that the CLI hands straight to clap's
//! `value_parser` (which uses `FromStr`), prints with `Display`, and lists with `NAMES`.
//! One macro keeps the name tables and the parsers from drifting apart.

/// Declares a fieldless enum with `name()`, `ALL`, `NAMES`, `Display` and `FromStr`
/// (case-insensitive; the error lists the accepted names).
macro_rules! named_enum {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident : $what:literal {
            $( $(#[$vmeta:meta])* $variant:ident => $text:literal ),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        $vis enum $name {
            $( $(#[$vmeta])* $variant ),+
        }

        impl $name {
            /// Every variant, in declaration order.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];
            /// The command-line name of every variant, in declaration order.
            pub const NAMES: &'static [&'static str] = &[$($text),+];

            /// The command-line name of this variant.
            pub fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $text),+
                }
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl std::str::FromStr for $name {
            type Err = $crate::error::ParseNameError;
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                let wanted = s.trim();
                $name::ALL
                    .iter()
                    .copied()
                    .find(|v| v.name().eq_ignore_ascii_case(wanted))
                    .ok_or_else(|| $crate::error::ParseNameError {
                        what: $what,
                        given: s.to_string(),
                        expected: $name::NAMES,
                    })
            }
        }
    };
}

pub(crate) use named_enum;
