"""What an adjusted scene makes: orthoimage, sensor-corrected image, fitted RPC, footprint."""
