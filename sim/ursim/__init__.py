"""UR controller stand-in: RTDE, dashboard, primary/secondary/real-time interfaces on loopback,
driving a simulated arm.

Run it with `fabkit ursim` / `python -m sim.ursim`, always in its own process (ur_rtde's
constructors hold the GIL). Modules, one job each:

- `rtde_vars`: RTDE variable names and official wire types, package framing;
- `rtde_server`: the RTDE v2 server (recipes, NOT_FOUND / IN_USE, streaming);
- `dashboard`: the dashboard server (exact controller replies);
- `script_ports`: ports 30001-30003: program framing (bounded), dispatch;
- `client_interfaces`: what 30001-30003 send (version, robot state, real-time package);
- `clients`: the client cap and registry, bounded line framing;
- `control_script`: ur_rtde's uploaded control script and its register protocol;
- `urscript`: the URScript subset fabkit writes (and ur_rtde's injected paths);
- `motion`: UR-style movej/movel planning with blends; `arm`: the motion executor;
- `controller`: state, safety, the periodic tick; `collision`: MuJoCo cell contacts;
- `admin`: fault injection and the command record; `server` / `cli`: options and start-up.
"""
