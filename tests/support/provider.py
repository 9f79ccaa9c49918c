"""What the plugin's Processing provider ('pushbroom') is expected to list."""

ALGORITHMS = ["pushbroom:simulatescene", "pushbroom:simulateblock", "pushbroom:importgcps", "pushbroom:importtiepoints", "pushbroom:importlines",
              "pushbroom:matchgcps", "pushbroom:matchtiepoints",
              "pushbroom:bundleadjust", "pushbroom:groundtoimage",
              "pushbroom:imagetoground", "pushbroom:footprint", "pushbroom:orthorectify",
              "pushbroom:exportrpc", "pushbroom:sensorcorrect", "pushbroom:preparedigitising",
              "pushbroom:snaplines"]
"""The ids of the provider's algorithms (the models aside)."""
MODELS = ["pushbroom:Simulate, adjust, orthorectify and export RPC",  # resources/models/*.model3
          "pushbroom:Simulate, match GCPs, adjust, orthorectify and export RPC",
          "pushbroom:Adjust with GCPs and control lines",
          "pushbroom:Three-line block: simulate, match tie points, adjust"]
"""The ids of the graphical models the provider ships (resources/models/*.model3)."""
