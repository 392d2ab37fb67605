//! Little-endian field access on byte slices, and the macros that generate the views'
//! boilerplate and per-field accessors. Callers check lengths first (`new_checked`), so
//! these index directly.

use crate::Field;

/// A fixed-width value stored little-endian in a [`Field`] of exactly its width.
pub(crate) trait Le: Copy {
    /// Reads the value from `b[f]`.
    fn read(b: &[u8], f: Field) -> Self;
    /// Writes the value into `b[f]`.
    fn write(self, b: &mut [u8], f: Field);
}

macro_rules! impl_le {
    ($($t:ty),*) => {$(
        impl Le for $t {
            #[inline]
            fn read(b: &[u8], f: Field) -> Self {
                let mut a = [0u8; size_of::<$t>()];
                a.copy_from_slice(&b[f]);
                <$t>::from_le_bytes(a)
            }
            #[inline]
            fn write(self, b: &mut [u8], f: Field) {
                b[f].copy_from_slice(&self.to_le_bytes());
            }
        }
    )*};
}
impl_le!(u8, u16, u32, u64, i32, f32);

/// Reads the little-endian value in `b[f]`.
#[inline]
pub(crate) fn get<V: Le>(b: &[u8], f: Field) -> V {
    V::read(b, f)
}

/// Writes `v` little-endian into `b[f]`.
#[inline]
pub(crate) fn put<V: Le>(b: &mut [u8], f: Field, v: V) {
    v.write(b, f);
}

/// Returns `Err(NonFinite)` for NaN and infinities.
pub(crate) fn finite(what: &'static str, v: f32) -> crate::Result<f32> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(crate::Error::NonFinite(what))
    }
}

/// Declares a zero-copy view `$name<T: AsRef<[u8]>>` over a buffer with `check_len` (the
/// given body, over the buffer's bytes `$b`), `new_unchecked`, `new_checked` (which calls
/// `check_len`) and `into_inner`.
macro_rules! view {
    (
        $(#[$meta:meta])* $name:ident;
        $(#[$check_meta:meta])* fn check_len($b:ident) $check:block
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy)]
        pub struct $name<T: AsRef<[u8]>> {
            buffer: T,
        }

        impl<T: AsRef<[u8]>> $name<T> {
            /// Wraps a buffer without checks: accessors may panic on a short buffer. Use
            /// `new_checked` for anything that came from outside.
            pub const fn new_unchecked(buffer: T) -> Self {
                $name { buffer }
            }

            /// Wraps a buffer after `check_len`: then no accessor can panic.
            pub fn new_checked(buffer: T) -> $crate::Result<Self> {
                let view = Self::new_unchecked(buffer);
                view.check_len()?;
                Ok(view)
            }

            $(#[$check_meta])*
            pub fn check_len(&self) -> $crate::Result<()> {
                let $b: &[u8] = self.buffer.as_ref();
                $check
            }

            /// The underlying buffer.
            pub fn into_inner(self) -> T {
                self.buffer
            }
        }
    };
}

/// Per-field accessors of a view: `getter[, setter]: type = field, "doc";`. The getter
/// reads the raw little-endian value of the field (no validation: see the view's `check`);
/// the setter, on a mutable buffer, writes it. The doc string names the field and its unit
/// and documents both.
macro_rules! fields {
    ($view:ident { $($get:ident $(, $set:ident)? : $ty:ty = $field:expr, $doc:literal;)* }) => {
        impl<T: AsRef<[u8]>> $view<T> {
            $(
                #[doc = $doc]
                #[inline]
                pub fn $get(&self) -> $ty {
                    $crate::bytes::get(self.buffer.as_ref(), $field)
                }
            )*
        }

        impl<T: AsRef<[u8]> + AsMut<[u8]>> $view<T> {
            $($(
                #[doc = concat!("Writes [`", stringify!($get), "`](Self::", stringify!($get), "): ", $doc)]
                #[inline]
                pub fn $set(&mut self, v: $ty) {
                    $crate::bytes::put(self.buffer.as_mut(), $field, v);
                }
            )?)*
        }
    };
}
