"""The built-in flight wheel laws, each a controller of hopper.controllers' API, loaded by name like a
user's: `pid` (the paper's, compiled into the kernel), `lqr`, `mpc`, `policy`, and `remote` (a
controller in another process over loopback TCP)."""
