//! Integration tests of the virtual printer.

mod quick;
