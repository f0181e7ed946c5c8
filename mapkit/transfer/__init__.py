"""Moving maps between robot and terminal: the MKT protocol and its transports."""
