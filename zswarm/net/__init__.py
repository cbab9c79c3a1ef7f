"""The distributed runtime's parts: wire messages, key expressions, Zenoh configuration and the one
asyncio bridge, fault injection, the pose table, security, the router, child processes and the run
specification every process shares. Never imports the simulator or the recording."""
