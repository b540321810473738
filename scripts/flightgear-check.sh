#!/usr/bin/env bash
# Fly the real FlightGear headless and check that `stratus flight --follow flightgear` records
# frames that follow it (docs/fly.md, "Checked against the real FlightGear"). Not run in CI:
# Debian's FlightGear and its base data are about 3 GB.
#
#   bash scripts/flightgear-check.sh            # as root on Debian 12 (apt-get), or with fgfs installed
#   DURATION=60 PORT=5599 WORK=/tmp/fgcheck bash scripts/flightgear-check.sh
#
# What it does: installs `flightgear` (fgfs in /usr/games) and Xvfb if missing; builds stratus;
# ingests the 2.5° GFS sample over Hawaii (the base data's scenery holds Oahu); copies
# docs/flightgear/stratus.xml into $FG_ROOT/Protocol; starts fgfs under xvfb-run and
# dbus-run-session (without a session bus fgfs 2020.3 stops at start) with a Cessna 172 in the
# air over Honolulu, sending the protocol twice: to stratus, and to a logger that stamps each
# line with the wall clock. Once the aircraft moves, it records DURATION s with
# `stratus flight --follow flightgear:PORT` (each frame's pose logged at debug level) and checks:
# packets received, none malformed, no frame held; every frame's pose within what 1 s of
# extrapolation allows of the packet FlightGear sent just before it; the aircraft moved and
# turned; the frames are not all the same picture. Exit 0 when every check holds.
set -euo pipefail
cd "$(dirname "$0")/.."

PORT=${PORT:-5599}
LOGPORT=$((PORT + 1))
DURATION=${DURATION:-60}
FPS=${FPS:-2}
WORK=${WORK:-$(mktemp -d /tmp/stratus-fgcheck.XXXXXX)}
FGFS=${FGFS:-/usr/games/fgfs}
FG_ROOT=${FG_ROOT:-/usr/share/games/flightgear}
mkdir -p "$WORK"
echo "== work folder $WORK"

if ! [ -x "$FGFS" ] || ! command -v xvfb-run >/dev/null || ! command -v dbus-run-session >/dev/null; then
    echo "== installing FlightGear, Xvfb and D-Bus (Debian packages)"
    apt-get update
    DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
        flightgear flightgear-data-base xvfb xauth dbus
fi
dpkg-query -W -f '${Package} ${Version}\n' flightgear 2>/dev/null || true

echo "== building stratus"
cargo build --release --bin stratus
# A copy: a rebuild while FlightGear loads does not change what is checked.
cp target/release/stratus "$WORK/stratus"
STRATUS=$WORK/stratus

echo "== map over Hawaii from data-samples/gfs-2011011012-f120-2p5.grib2"
"$STRATUS" ingest data-samples/gfs-2011011012-f120-2p5.grib2 --region 10,32,-170,-145 \
    --size 256x256 --out "$WORK/hawaii.png"

cp docs/flightgear/stratus.xml "$FG_ROOT/Protocol/stratus.xml"

pids=()
cleanup() {
    for p in "${pids[@]}"; do
        # Each was started in a session of its own: its whole process group goes.
        kill -TERM -- "-$p" 2>/dev/null || kill -TERM "$p" 2>/dev/null || true
    done
}
trap cleanup EXIT

echo "== packet logger on UDP $LOGPORT"
setsid python3 - "$LOGPORT" "$WORK/fg-packets.txt" <<'EOF' &
import socket, sys, time
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", int(sys.argv[1])))
with open(sys.argv[2], "w", buffering=1) as f:
    while True:
        data, _ = s.recvfrom(65536)
        f.write("%.3f %s\n" % (time.time(), data.decode("utf-8", "replace").strip()))
EOF
pids+=($!)

echo "== fgfs (c172p in the air over PHNL, 6000 ft, 100 kt, heading 90) under xvfb-run + dbus-run-session"
FGOPTS=(--aircraft=c172p --airport=PHNL --in-air --altitude=6000 --vc=100 --heading=90
    --disable-sound --disable-splash-screen --disable-ai-traffic --disable-real-weather-fetch
    --timeofday=noon --geometry=320x240 --disable-random-objects --disable-random-vegetation
    --disable-random-buildings --disable-panel --disable-hud --fog-fastest
    --disable-specular-highlight --disable-horizon-effect
    # Software OpenGL under Xvfb: draw next to nothing, so the main loop (which sends the
    # packets) keeps its rate.
    --prop:/sim/rendering/draw-mask/terrain=false --prop:/sim/rendering/draw-mask/models=false
    --prop:/sim/rendering/draw-mask/aircraft=false --prop:/sim/rendering/draw-mask/clouds=false
    --prop:/sim/rendering/shaders/quality-level=0
    "--generic=socket,out,10,127.0.0.1,$PORT,udp,stratus"
    "--generic=socket,out,10,127.0.0.1,$LOGPORT,udp,stratus")
setsid xvfb-run -a -s "-screen 0 800x600x24" dbus-run-session -- "$FGFS" "${FGOPTS[@]}" \
    >"$WORK/fgfs.log" 2>&1 &
pids+=($!)

echo "== waiting for the aircraft to move (FlightGear sends its start position while it loads)"
start=$(date +%s)
until python3 - "$WORK/fg-packets.txt" <<'EOF'
import sys
seen = set()
for line in open(sys.argv[1]):
    f = line.split(" ", 1)[1].split(",")
    seen.add((f[0], f[1]))
sys.exit(0 if len(seen) > 5 else 1)
EOF
do
    if (($(date +%s) - start > 600)); then
        echo "FAIL: FlightGear sent no moving aircraft in 600 s; its log ends:"
        tail -n 20 "$WORK/fgfs.log"
        exit 1
    fi
    sleep 2
done
echo "   moving after $(($(date +%s) - start)) s"

echo "== stratus flight --follow flightgear:$PORT --duration $DURATION --fps $FPS"
set +e
t0=$(date +%s)
RUST_LOG=stratus::follow=debug NODEVICE_SELECT=1 "$STRATUS" flight --map "$WORK/hawaii.json" \
    --follow "flightgear:$PORT" --duration "$DURATION" --fps "$FPS" --size 320x180 \
    --preset fast --out "$WORK/frames" >"$WORK/stratus.out" 2>"$WORK/stratus.err"
rc=$?
set -e
echo "   stratus ran $(($(date +%s) - t0)) s"
cleanup
pids=()
grep -v "stratus::follow::frames" "$WORK/stratus.err" | head -n 20
cat "$WORK/stratus.out"
if [ "$rc" != 0 ]; then
    echo "FAIL: stratus exited $rc"
    exit 1
fi

echo "== checks"
python3 - "$WORK" "$DURATION" "$FPS" <<'EOF'
import hashlib, math, os, re, sys

work, duration, fps = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
out = open(os.path.join(work, "stratus.out")).read()
err = open(os.path.join(work, "stratus.err")).read()
fails = []

def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        fails.append(what)

m = re.search(r"FlightGear: (\d+) packets, (\d+) malformed \(ignored\); (\d+) of (\d+) frames held", out)
check(m is not None, "stratus printed its packet line")
if m is None:
    sys.exit(1)
packets, malformed, held, frames = map(int, m.groups())
check(packets > 0, f"packets received: {packets}")
check(malformed == 0, f"malformed: {malformed}")
check(held == 0, f"frames held (simulator silent): {held}")
check(frames == math.ceil(duration * fps), f"frames: {frames}")

R = 6371000.0
def dist(a, b):
    la1, la2 = math.radians(a[0]), math.radians(b[0])
    dla, dlo = la2 - la1, math.radians(b[1] - a[1])
    s = math.sin(dla / 2) ** 2 + math.cos(la1) * math.cos(la2) * math.sin(dlo / 2) ** 2
    return 2 * R * math.asin(min(1.0, math.sqrt(s)))

def angle(a, b):
    return abs((a - b + 180.0) % 360.0 - 180.0)

sent = []
for line in open(os.path.join(work, "fg-packets.txt")):
    t, rest = line.split(" ", 1)
    v = [float(x) for x in rest.split(",")]
    # lat, lon, alt (ft), heading, pitch, roll, ground speed (kt), vertical speed (ft/s)
    sent.append((float(t), v[0], v[1], v[2] * 0.3048, v[3], v[6] * 1852 / 3600, v[7] * 0.3048))
poses = []
pat = re.compile(r"frame (\d+) unix ([\d.]+) lat (\S+) lon (\S+) alt (\S+) heading (\S+) pitch (\S+) roll (\S+) held (\w+)")
for line in err.splitlines():
    f = pat.search(line)
    if f:
        poses.append((float(f[2]), float(f[3]), float(f[4]), float(f[5]), float(f[6])))
check(len(poses) == frames, f"frame poses logged: {len(poses)}")

# Per frame: how far its pose is from the latest packet the logger had, and how far the
# extrapolation allows (below); the worst of each and the least margin.
rows = []
for (t, lat, lon, alt, hdg) in poses:
    k = sum(1 for p in sent if p[0] <= t) - 1
    if k < 0:
        continue
    p, q, o = sent[k], sent[min(k + 1, len(sent) - 1)], sent[max(k - 1, 0)]
    # The pose is the latest packet stratus had (the logger's, or the one before if the two
    # sockets raced) flown on for its age (at most 1 s) at its ground speed and climb: allow
    # the motion of one packet interval besides, and 5 m (2 m up, 0.5 deg) of rounding.
    age = min(t - p[0], 1.0)
    gap = max(q[0] - p[0], p[0] - o[0])
    d, dz, dh = dist((lat, lon), (p[1], p[2])), abs(alt - p[3]), angle(hdg, p[4])
    allow = (p[5] * (age + gap) + 5.0, abs(p[6]) * (age + gap) + 2.0,
             max(angle(q[4], p[4]), angle(p[4], o[4])) + 0.5)
    rows.append(((d, dz, dh), allow))
for i, (name, unit) in enumerate([("position", "m"), ("altitude", "m"), ("heading", "deg")]):
    worst = max(r[0][i] for r in rows)
    margin = min(r[1][i] - r[0][i] for r in rows)
    check(margin > 0, f"frame {name} vs FlightGear's packet before it: worst {worst:.2f} {unit} off, every frame within its allowance (least margin {margin:.2f} {unit})")

moved = sum(dist((a[1], a[2]), (b[1], b[2])) for a, b in zip(poses, poses[1:]))
turned = max(angle(p[4], poses[0][4]) for p in poses)
climb = poses[-1][3] - poses[0][3]
check(moved > 500, f"the frames' camera travelled {moved:.0f} m (frame to frame)")
print(f"     heading changed by up to {turned:.1f} deg; altitude {poses[0][3]:.0f} -> {poses[-1][3]:.0f} m")
sp = [p[5] for p in sent if poses[0][0] <= p[0] <= poses[-1][0]]
if sp:
    print(f"     FlightGear's ground speed over the recording: {min(sp)/0.514444:.0f}-{max(sp)/0.514444:.0f} kt")
shots = sorted(f for f in os.listdir(os.path.join(work, "frames")) if f.endswith(".png"))
digests = {hashlib.sha256(open(os.path.join(work, "frames", f), "rb").read()).hexdigest() for f in shots}
check(len(digests) > 1, f"distinct frames: {len(digests)} of {len(shots)}")
sys.exit(1 if fails else 0)
EOF
echo "== flightgear-check: all checks passed"
