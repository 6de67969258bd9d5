//! Map storage: random-access reads of the map product (design §4) from
//! non-volatile memory, into caller buffers.

use crate::error::ErrorType;
use vtsm_core::map::MapView;

/// Read-only storage holding one map product.
pub trait MapStore: ErrorType {
    /// Length of the stored map product in bytes.
    ///
    /// # Contract
    /// * Constant while the store is open; `Ok(0)` means no product is stored.
    fn len(&mut self) -> Result<u32, Self::Error>;

    /// Whether no product is stored (`len() == 0`).
    ///
    /// # Contract
    /// * Same errors as [`MapStore::len`].
    fn is_empty(&mut self) -> Result<bool, Self::Error> {
        Ok(self.len()? == 0)
    }

    /// Read `buf.len()` bytes starting at byte `offset` of the product.
    ///
    /// # Contract
    /// * On `Ok(())` all of `buf` is filled with bytes `offset..offset+buf.len()`.
    /// * A range that does not lie inside `0..len()` is an error of kind
    ///   [`Other`](crate::ErrorKind::Other); nothing is read.
    /// * A short read is kind [`Truncated`](crate::ErrorKind::Truncated), a
    ///   detected media error (ECC) is [`Corrupted`](crate::ErrorKind::Corrupted),
    ///   a busy device that did not answer in time is
    ///   [`Timeout`](crate::ErrorKind::Timeout). After an error the contents of
    ///   `buf` are unspecified.
    /// * Undetected corruption is possible: callers check the product's CRCs.
    /// * Never writes outside `buf`; keeps no reference to it.
    fn read_range(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), Self::Error>;

    /// The whole stored product as directly addressable memory, when the
    /// storage is memory-mapped (execute-in-place NOR flash, MRAM, a
    /// mass-memory window); `None` (the default) when it is read only through
    /// [`MapStore::read_range`].
    ///
    /// # Contract
    /// * `Some(bytes)`: `bytes` are the product, the same bytes
    ///   `read_range` returns, and stay unchanged while the store is
    ///   borrowed; `bytes.len()` is the product's length.
    /// * The answer (`Some` or `None`) is constant while the store is open.
    /// * Undetected corruption is possible: callers check the product's CRCs
    ///   on these bytes before use, as on bytes read.
    fn mapped(&self) -> Option<&[u8]> {
        None
    }

    /// The product as a view its owner has already checked
    /// ([`MapView::new_checked`]), when there is one: a host that loaded the
    /// product from a file and checked it there hands the runner that view,
    /// and the runner uses it as is, without reading, copying or checking
    /// the bytes again. `None` (the default, and every flight store): the
    /// runner checks the product itself.
    ///
    /// # Contract
    /// * `Some(view)`: `view.bytes()` are the product (the bytes
    ///   [`MapStore::mapped`] and `read_range` give, when they give any) and
    ///   stay unchanged while the store is borrowed.
    /// * The answer (`Some` or `None`) is constant while the store is open.
    fn checked(&self) -> Option<MapView<'_>> {
        None
    }
}

impl<T: MapStore + ?Sized> MapStore for &mut T {
    fn len(&mut self) -> Result<u32, Self::Error> {
        T::len(self)
    }
    fn read_range(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), Self::Error> {
        T::read_range(self, offset, buf)
    }
    fn mapped(&self) -> Option<&[u8]> {
        T::mapped(self)
    }
    fn checked(&self) -> Option<MapView<'_>> {
        T::checked(self)
    }
}
