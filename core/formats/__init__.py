"""Files that hold a scene: scene JSON and its schema, DIMAP, Maxar XML, RPC text/RPB/DIMAP RPC."""
