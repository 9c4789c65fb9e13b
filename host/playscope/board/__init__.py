"""Tables to the board: table-file checks, the link (frame codec through cffi, transports, the
emulated USB board), flashing with its bit-for-bit check, the on-line update, and the board side
of run-insitu."""
