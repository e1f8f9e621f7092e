// vdb_shim.cpp: placeholder until the module lands.
