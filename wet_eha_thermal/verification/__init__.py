"""Independent checks of the model (finite elements); nothing at run time imports them."""
