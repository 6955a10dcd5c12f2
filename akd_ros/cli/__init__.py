"""Command-line tools: akd-sim (the virtual AKD), akd-scan (bus scan), akd-sdo (SDO access)."""
