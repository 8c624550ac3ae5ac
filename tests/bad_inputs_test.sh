#!/usr/bin/env bash
# Bad inputs through the real executables (CTest bad_inputs; issue 17, docs/reliability.md).
#
#   bad_inputs_test.sh BUILD_DIR WORKDIR
#
# Every case must: exit with code 1; print exactly one line on stderr, of the form
# "<program>: error: <subject>: <reason>", whose text matches the case's pattern (the
# file or option at fault and the problem); and leave the output it names untouched (a
# file holding "old output" before the run holds it after, and no temporary file is left
# beside it). Missing files, wrong formats, NaN/Inf pixels, corrupted and mismatched
# transport files, degenerate meshes, nonsense parameters, unwritable outputs, absurd
# memory needs, bad light and job files, command-line usage errors. One case must succeed:
# `prt-relight info` describes the good transport file (the refusals beside it would pass
# for a tool that refused everything).
set -u

if [ $# -ne 2 ]; then
    echo "usage: $0 BUILD_DIR WORKDIR" >&2
    exit 2
fi
BUILD=$1 WORK=$2
PRECOMPUTE=$BUILD/bin/prt-precompute
RELIGHT=$BUILD/bin/prt-relight
POINTLIGHT=$BUILD/bin/prt-pointlight
REFERENCE=$BUILD/bin/prt-reference
VERTEX_ERROR=$BUILD/bin/prt-vertex-error
COMPARE=$BUILD/bin/prt-compare
ENVCHECK=$BUILD/bin/prt-envcheck
MAKE_SCENE=$BUILD/bin/prt-make-test-scene
MAKE_ASSET=$BUILD/bin/prt-make-asset

rm -rf "$WORK"
mkdir -p "$WORK"
cd "$WORK" || exit 1
S=scene

# --- inputs -------------------------------------------------------------------------
if [ -x "$MAKE_SCENE" ]; then
    "$MAKE_SCENE" scene "$S" > /dev/null 2>&1 || { echo "FAIL: prt-make-test-scene"; exit 1; }
else
    echo "SKIP: prt-make-test-scene not built (the viewer is off)"
    exit 77
fi
"$PRECOMPUTE" "$S/torus.ply" --size-mm 20 --cubemap-size 8 --samples 2000 -q -o "$S/torus.prt" > /dev/null 2>&1 \
    || { echo "FAIL: prt-precompute of the test scene"; exit 1; }
: > empty.obj
printf 'garbage\nmore garbage\n' > garbage.ply
printf 'v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > nan.obj
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n' > index.obj
printf 'v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n' > flat.obj
head -c 1000 "$S/torus.prt" > truncated.prt
cp "$S/torus.prt" corrupted.prt
printf '\xff\xfe' | dd of=corrupted.prt bs=1 seek=300000 conv=notrunc status=none
cp "$S/sky.exr" not-a-transport.prt
printf 'not a PNG at all' > fake.png
oiiotool --pattern constant:color=0,1,1 64x32 3 -d float --powc -1,1,1 -o inf.exr > /dev/null 2>&1 \
    || { echo "FAIL: oiiotool (openimageio-tools) could not write inf.exr"; exit 1; }
oiiotool --pattern constant:color=0.5,0.5,0.5 32x32 3 -d float -o small.exr > /dev/null 2>&1
printf '{"jobs": [ {"mesh": "x.obj" ' > broken-job.json
printf '{"jobs": [ {"mesh": "%s", "output": "j.prt", "sampels": 100} ]}\n' "$S/torus.ply" > typo-job.json
printf '{"lights": [ {"type": "point", "positon": [0, 50, 0], "intensity": 1} ]}\n' > typo-lights.json
printf '{"lights": [ {"type": "point", "position": [0, 50, 0], "intensity": -1} ]}\n' > negative-lights.json
mkdir -p outdir
: > a-file
# glTF assets (docs/assets.md): the torus as a textured .gltf (+ .bin, PNG) and .glb, and
# broken copies of them.
"$MAKE_ASSET" "$S/torus.ply" -o torus.gltf > /dev/null 2>&1 && "$MAKE_ASSET" "$S/torus.ply" -o torus.glb > /dev/null 2>&1 \
    || { echo "FAIL: prt-make-asset could not write the torus"; exit 1; }
sed 's/"mode":4/"mode":1/' torus.gltf > lines.gltf
sed 's/"mode":4/"mode":0/' torus.gltf > points.gltf
sed '0,/"byteOffset":0,/s//"byteOffset":99999999,/' torus.gltf > view.gltf
head -c 300 torus.gltf > broken.gltf
head -c 5000 torus.glb > truncated.glb

failures=0 cases=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# expect NAME PATTERN OUTPUT COMMAND...: OUTPUT is a file path that must survive
# untouched ("-" for none). The pattern is an extended regular expression matched
# against the single stderr line.
expect() {
    local name=$1 pattern=$2 output=$3
    shift 3
    cases=$((cases + 1))
    if [ "$output" != "-" ]; then
        mkdir -p "$(dirname "$output")" 2> /dev/null
        [ -d "$(dirname "$output")" ] && printf 'old output' > "$output"
    fi
    "$@" > stdout.txt 2> stderr.txt
    local rc=$?
    # Stage summaries of long runs ("pass 1: 2000 samples in 0.1 s (1.4e+04 samples/s)")
    # may precede the error; every other line counts.
    grep -vE '^[a-z0-9 ():,-]+: [0-9]+ [a-z ()0-9]+ in [0-9.]+ (s|min|h)[^(]*\([0-9.e+]+ [a-z ]+/s\)$' stderr.txt > errors.txt
    mv errors.txt stderr.txt
    local lines
    lines=$(wc -l < stderr.txt)
    local message
    message=$(cat stderr.txt)
    local problems=""
    [ $rc -eq 1 ] || problems+=" exit $rc (expected 1);"
    [ "$lines" -eq 1 ] || problems+=" $lines stderr lines (expected 1);"
    echo "$message" | grep -qE "^prt-[a-z-]+: error: " || problems+=" not 'prog: error: ...';"
    echo "$message" | grep -qE -- "$pattern" || problems+=" message does not match /$pattern/;"
    if [ "$output" != "-" ] && [ -d "$(dirname "$output")" ]; then
        [ "$(cat "$output" 2> /dev/null)" = "old output" ] || problems+=" $output was touched;"
        if ls -a "$(dirname "$output")" | grep -q '\.tmp'; then problems+=" a temporary file was left;"; fi
        rm -f "$output"
    fi
    if [ -z "$problems" ]; then
        echo "PASS: $name: $message"
    else
        echo "$message" | head -5
        fail "$name:$problems"
    fi
}

P="$PRECOMPUTE"
O=outdir/out.prt
# --- prt-precompute: meshes -----------------------------------------------------------
expect "precompute: missing mesh" "missing\.obj: no such file" $O $P missing.obj -q -o $O
expect "precompute: empty mesh" "empty\.obj: .*empty" $O $P empty.obj -q -o $O
expect "precompute: not a PLY" "garbage\.ply: not a PLY" $O $P garbage.ply -q -o $O
expect "precompute: NaN vertex" "nan\.obj: .*non-finite" $O $P nan.obj -q -o $O
expect "precompute: index out of range" "index\.obj: .*vertex 8" $O $P index.obj -q -o $O
expect "precompute: degenerate mesh" "flat\.obj: .*degenerate" $O $P flat.obj -q -o $O
expect "precompute: baseline albedo above 1" "--albedo: each channel must be in \[0, 1\]" $O \
    $P "$S/torus.ply" --baseline diffuse-brdf --albedo 0.5,1.5,0.5 -q -o $O
expect "precompute: albedo without baseline" "--albedo: only with --baseline" $O $P "$S/torus.ply" --albedo 0.5 -q -o $O
expect "precompute: baseline with blocks" "--block-coefficients: not with --baseline" $O \
    $P "$S/torus.ply" --baseline diffuse-brdf --block-coefficients 64 -q -o $O
expect "precompute: glTF LINES primitive" "lines\.gltf: mesh 0 primitive 0 is LINES" $O $P lines.gltf -q -o $O
expect "precompute: glTF POINTS primitive" "points\.gltf: mesh 0 primitive 0 is POINTS" $O $P points.gltf -q -o $O
expect "precompute: glTF buffer view out of range" "view\.gltf: .*out of range" $O $P view.gltf -q -o $O
expect "precompute: broken glTF JSON" "broken\.gltf: invalid glTF JSON" $O $P broken.gltf -q -o $O
expect "precompute: truncated .glb" "truncated\.glb: truncated" $O $P truncated.glb -q -o $O
# --- prt-make-asset -------------------------------------------------------------------
A=outdir/asset.glb
expect "make-asset: missing mesh" "missing\.obj: no such file" $A "$MAKE_ASSET" missing.obj -o $A
expect "make-asset: texture not an image" "fake\.png" $A "$MAKE_ASSET" "$S/torus.ply" --texture fake.png -o $A
expect "make-asset: unknown projection" "--projection" $A "$MAKE_ASSET" "$S/torus.ply" --projection cube -o $A
expect "make-asset: output not glTF" "asset\.fbx: .*extension" - "$MAKE_ASSET" "$S/torus.ply" -o outdir/asset.fbx
# --- prt-precompute: options ----------------------------------------------------------
expect "precompute: unknown option" "--bogus" $O $P "$S/torus.ply" --bogus -q -o $O
expect "precompute: missing value" "--output" - $P "$S/torus.ply" -o
expect "precompute: negative size" "--size-mm" $O $P "$S/torus.ply" --size-mm -5 -q -o $O
expect "precompute: unknown material" "Unobtainium: unknown material" $O $P "$S/torus.ply" -m Unobtainium -q -o $O
expect "precompute: cubemap not a power of two" "--cubemap-size" $O $P "$S/torus.ply" --cubemap-size 33 -q -o $O
expect "precompute: zero coefficients" "--coefficients" $O $P "$S/torus.ply" --coefficients 0 -q -o $O
expect "precompute: block coefficients beyond 6 N^2" "--block-coefficients" $O $P "$S/torus.ply" --block-coefficients 7000 -q -o $O
expect "precompute: negative threads" "--threads" $O $P "$S/torus.ply" --threads -1 -q -o $O
expect "precompute: eta out of range" "eta: .*0\.5, 2\.5" $O $P "$S/torus.ply" --eta 0 -q -o $O
expect "precompute: negative epsilon" "--epsilon" $O $P "$S/torus.ply" --epsilon -1 -q -o $O
expect "precompute: unknown component" "--components" $O $P "$S/torus.ply" --components xs -q -o $O
expect "precompute: g out of range" "--g|g:" $O $P "$S/torus.ply" --components ms,ss --g 1.5 -q -o $O
expect "precompute: absurd sample count" "memory: the job needs about .* GB .*available" $O \
    $P "$S/torus.ply" --samples 800000000 -q -o $O
expect "precompute: over --max-memory" "allowed by --max-memory" $O \
    $P "$S/torus.ply" --samples 100000 --max-memory 0.01 -q -o $O
expect "precompute: negative --max-memory" "--max-memory" $O $P "$S/torus.ply" --max-memory -1 -q -o $O
expect "precompute: missing output directory" "nodir/o\.prt: directory 'nodir' does not exist" - \
    $P "$S/torus.ply" -q -o nodir/o.prt
expect "precompute: output under a file" "a-file/o\.prt" - $P "$S/torus.ply" -q -o a-file/o.prt
expect "precompute: broken job file" "broken-job\.json" - $P --jobs broken-job.json
expect "precompute: misspelt job key" "typo-job\.json.*sampels" - $P --jobs typo-job.json

# --- prt-relight render: transport files and environments -------------------------------
R="$RELIGHT render"
F=outdir/frame
expect "render: missing transport" "missing\.prt: no such file" $F.exr $R "$S/torus.ply" -t missing.prt -e "$S/sky.exr" -o $F
expect "render: mesh does not match" "torus\.prt: transport file was made for a mesh with 1152 vertices" $F.exr \
    $R "$S/sphere.ply" -t "$S/torus.prt" -e "$S/sky.exr" -o $F
expect "render: truncated transport" "truncated\.prt" $F.exr $R "$S/torus.ply" -t truncated.prt -e "$S/sky.exr" -o $F
expect "render: corrupted transport" "corrupted\.prt: .*(checksum|CRC|corrupt)" $F.exr \
    $R "$S/torus.ply" -t corrupted.prt -e "$S/sky.exr" -o $F
expect "render: not a transport file" "not-a-transport\.prt" $F.exr \
    $R "$S/torus.ply" -t not-a-transport.prt -e "$S/sky.exr" -o $F
expect "render: missing environment" "nowhere\.exr" $F.exr $R "$S/torus.ply" -t "$S/torus.prt" -e nowhere.exr -o $F
expect "render: Inf pixels" "inf\.exr: .*(Inf|non-finite)" $F.exr $R "$S/torus.ply" -t "$S/torus.prt" -e inf.exr -o $F
expect "render: not an image" "fake\.png" $F.exr $R "$S/torus.ply" -t "$S/torus.prt" -e fake.png -o $F
expect "render: samples per pixel not a square" "--spp: must be a square number" $F.exr \
    $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --spp 8 -o $F
expect "render: unknown tone mapping" "--tonemap: unknown operator 'gamma'" $F.exr \
    $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --tonemap gamma -o $F
expect "render: square environment" "small\.exr: .*(2:1|lat-long|aspect|twice)" $F.exr \
    $R "$S/torus.ply" -t "$S/torus.prt" -e small.exr -o $F
expect "render: zero width" "-W" $F.exr $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" -W 0 -o $F
expect "render: zero fov" "--fov" $F.exr $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --fov 0 -o $F
expect "render: component the file lacks" "torus\.prt: has no single-scattering component" $F.exr \
    $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --components ss -o $F
expect "render: sun threshold of zero" "--sun-threshold: must be a finite number > 0" $F.exr \
    $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --sun-split --sun-threshold 0 -o $F
expect "render: sun cell of zero degrees" "--sun-cell: must be in \(0, 90\] degrees" $F.exr \
    $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --sun-split --sun-cell 0 -o $F
expect "render: unknown sun method" "--sun-method: must be jb, cache or brute, got 'tsis'" $F.exr \
    $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --sun-split --sun-method tsis -o $F

# --- a sample count far below the convergence rule: a warning with the rule's count ------
# (runs, exit 0, one warning line naming the rule's count; the good job above, at half
# the rule's count, has none)
cases=$((cases + 1))
if "$PRECOMPUTE" "$S/torus.ply" --size-mm 20 --cubemap-size 8 --samples 64 -q -o few.prt > /dev/null 2> few.txt \
    && [ -f few.prt ] && [ "$(wc -l < few.txt)" -eq 1 ] \
    && grep -q "^prt-precompute: warning: 64 samples (--samples) are far below the convergence rule's [0-9]" few.txt \
    && "$PRECOMPUTE" "$S/torus.ply" --size-mm 20 --cubemap-size 8 --samples 2000 -q -o enough.prt > /dev/null \
        2> enough.txt && [ ! -s enough.txt ]; then
    echo "PASS: precompute: too few samples: $(cat few.txt)"
else
    cat few.txt enough.txt 2> /dev/null | head -5
    fail "precompute: too few samples are not warned about (or the right count is)"
fi

# --- prt-relight info -------------------------------------------------------------------
I="$RELIGHT info"
expect "info: missing transport" "missing\.prt: no such file" - $I missing.prt
expect "info: truncated transport" "truncated\.prt" - $I truncated.prt
expect "info: not a transport file" "not-a-transport\.prt" - $I not-a-transport.prt
expect "info --full: corrupted transport" "corrupted\.prt: .*(checksum|CRC|corrupt)" - $I --full corrupted.prt
# The good file is described (the one case here that must succeed): header only, then
# loaded (one header line, byte counts labelled by where they live); header only, the
# corrupted file passes too, since its vectors are not read (the output says so).
cases=$((cases + 1))
if $I "$S/torus.prt" > info.txt 2> stderr.txt && grep -q "multiple scattering: 1152 vertices.* on disk" info.txt \
    && grep -q "^vectors: not read or verified" info.txt \
    && $I --full "$S/torus.prt" > info-full.txt 2>> stderr.txt && grep -q "in memory" info-full.txt \
    && grep -q "^transport file, format version" info-full.txt && [ "$(grep -c '^transport file' info-full.txt)" -eq 1 ] \
    && grep -q "^loaded and verified in" info-full.txt && ! grep -q "not read or verified" info-full.txt \
    && $I corrupted.prt > /dev/null 2>> stderr.txt && [ ! -s stderr.txt ]; then
    echo "PASS: info: the good file is described"
else
    cat info.txt info-full.txt stderr.txt 2> /dev/null | head -20
    fail "info: the good file is not described"
fi

# --- glTF assets pair with the transport file of the mesh they were made from ---------
# (the asset's mesh is loadMesh's, vertex for vertex: same fingerprint)
cases=$((cases + 1))
if $R torus.glb -t "$S/torus.prt" -e "$S/sky.exr" -W 32 -H 32 -o outdir/glb > /dev/null 2> stderr.txt \
    && $R torus.gltf -t "$S/torus.prt" -e "$S/sky.exr" -W 32 -H 32 -o outdir/gltf > /dev/null 2>> stderr.txt \
    && [ -f outdir/glb.exr ] && [ -f outdir/gltf.exr ]; then
    echo "PASS: render: the torus as .glb and .gltf pairs with its transport file"
else
    head -5 stderr.txt
    fail "render: a glTF made from the torus does not pair with its transport file"
fi

# --- prt-pointlight -------------------------------------------------------------------
L="$POINTLIGHT"
expect "pointlight: no light" "--light: no light" $F.exr $L "$S/torus.ply" -o $F
expect "pointlight: samples per pixel not a square" "--spp: must be a square number" $F.exr \
    $L "$S/torus.ply" --size-mm 20 --light point:30,30,30:0.01 --spp 2 -o $F
expect "pointlight: bad light syntax" "--light point:1,2:1" $F.exr $L "$S/torus.ply" --light point:1,2:1 -o $F
expect "pointlight: light inside the object" "inside the object" $F.exr \
    $L "$S/torus.ply" --size-mm 20 --light point:5,0,0:1 -o $F
expect "pointlight: misspelt lights key" "typo-lights\.json.*positon" $F.exr $L "$S/torus.ply" --lights typo-lights.json -o $F
expect "pointlight: negative intensity" "negative-lights\.json" $F.exr \
    $L "$S/torus.ply" --lights negative-lights.json -o $F
expect "pointlight: unknown method" "--method" $F.exr $L "$S/torus.ply" --light point:0,50,0:1 --method magic -o $F
expect "pointlight: atlas not a power of two" "--atlas-size" $F.exr \
    $L "$S/torus.ply" --light point:0,50,0:1 --method tsis --atlas-size 1000 -o $F
expect "pointlight: unknown split" "--split" $F.exr $L "$S/torus.ply" --light point:0,50,0:1 --method tsis --split both -o $F
expect "pointlight: zero samples" "--tsis-samples" $F.exr \
    $L "$S/torus.ply" --light point:0,50,0:1 --method tsis --tsis-samples 0 -o $F
expect "pointlight: cache bound a = 0" "--a" $F.exr $L "$S/torus.ply" --light point:0,50,0:1 --a 0 -o $F
expect "pointlight: unknown near-field rule" "--near-field" $F.exr \
    $L "$S/torus.ply" --light point:0,50,0:1 --near-field exact -o $F

# --- prt-reference, prt-compare, prt-envcheck ----------------------------------------------
expect "reference: missing environment" "nowhere\.exr" $F.exr \
    $REFERENCE "$S/torus.ply" -t "$S/torus.prt" -e nowhere.exr -W 16 -H 16 -o $F
expect "reference: the file's seed" "--seed" $F.exr \
    $REFERENCE "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" -W 16 -H 16 --seed 1 -o $F
expect "reference: pixel stride with samples per pixel" "--pixel-stride: not with --spp" $F.exr \
    $REFERENCE "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" -W 16 -H 16 --pixel-stride 2 --spp 4 -o $F
expect "reference: both an environment and lights" "--environment: .*not both" $F.exr \
    $REFERENCE "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --light point:0,50,0:1 -W 16 -H 16 -o $F
expect "reference: no light at all" "--environment: no light" $F.exr \
    $REFERENCE "$S/torus.ply" -t "$S/torus.prt" -W 16 -H 16 -o $F
expect "reference: environment without a transport file" "--transport" $F.exr \
    $REFERENCE "$S/torus.ply" -e "$S/sky.exr" -W 16 -H 16 -o $F
expect "reference: single scattering under lights" "--components: .*environments only" $F.exr \
    $REFERENCE "$S/torus.ply" --light point:0,50,0:1 --components ms,ss -W 16 -H 16 -o $F
expect "reference: a size with the transport file" "--size-mm: .*fixes the size" $F.exr \
    $REFERENCE "$S/torus.ply" -t "$S/torus.prt" --light point:0,50,0:1 --size-mm 20 -W 16 -H 16 -o $F
expect "reference: a light inside the object" "inside the object" $F.exr \
    $REFERENCE "$S/torus.ply" --size-mm 20 --light point:5,0,0:1 -W 16 -H 16 -o $F
expect "reference: misspelt light scene key" "typo-lights\.json" $F.exr \
    $REFERENCE "$S/torus.ply" --lights typo-lights.json -W 16 -H 16 -o $F
expect "reference: zero pixel stride" "--pixel-stride" $F.exr \
    $REFERENCE "$S/torus.ply" --light point:0,50,0:1 --pixel-stride 0 -W 16 -H 16 -o $F
expect "vertex-error: another mesh" "torus\.prt: .*mesh" - \
    $VERTEX_ERROR "$S/sphere.ply" -t "$S/torus.prt" -e "$S/sky.exr"
expect "vertex-error: zero stride" "--stride" - \
    $VERTEX_ERROR "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --stride 0
expect "vertex-error: corrupted transport" "corrupted\.prt" - \
    $VERTEX_ERROR "$S/torus.ply" -t corrupted.prt -e "$S/sky.exr"
expect "vertex-error: --material on a plain file" "torus\.prt: is not editable" - \
    $VERTEX_ERROR "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" --material Ketchup
expect "compare: missing image" "nowhere\.exr" - $COMPARE nowhere.exr "$S/sky.exr"
expect "compare: different sizes" "(size|dimension)" - $COMPARE small.exr "$S/sky.exr"
expect "envcheck: Inf pixels" "inf\.exr" - $ENVCHECK inf.exr --size 8 -o outdir/cube
expect "envcheck: cubemap size" "--size" - $ENVCHECK "$S/sky.exr" --size 33 -o outdir/cube

# --- a full disk while writing: every writer, through each executable ------------------
# RLIMIT_FSIZE stands in for a full disk (no mount needed): with SIGXFSZ ignored a write
# past the limit fails with EFBIG ("File too large") exactly where ENOSPC would. The old
# output must survive and no temporary may be left (common/atomic_file.h).
limited() {
    local kb=$1
    shift
    ( trap '' XFSZ; ulimit -f "$kb"; exec "$@" )
}
FULL="(File too large|No space left)"
expect "disk full: precompute transport file" "outdir/out\.prt: .*$FULL" $O \
    limited 32 $P "$S/torus.ply" --size-mm 20 --cubemap-size 8 --samples 2000 -q -o $O
printf '{"jobs": [{"mesh": "%s", "output": "%s", "size-mm": 20, "cubemap-size": 8, "samples": 2000}]}\n' \
    "$S/torus.ply" "$S/torus.prt" > up-to-date-job.json
expect "disk full: precompute --summary-json" "outdir/summary\.json: .*$FULL" outdir/summary.json \
    limited 1 $P --jobs up-to-date-job.json --summary-json outdir/summary.json
expect "disk full: render EXR" "outdir/frame\.exr: .*$FULL" $F.exr \
    limited 16 $R "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" -W 256 -H 256 -o $F
expect "disk full: pointlight EXR" "outdir/frame\.exr: .*$FULL" $F.exr \
    limited 16 $L "$S/torus.ply" --size-mm 20 --light point:0,50,0:1 -W 256 -H 256 -o $F
expect "disk full: reference EXR" "outdir/frame\.exr: .*$FULL" $F.exr \
    limited 16 $REFERENCE "$S/torus.ply" -t "$S/torus.prt" -e "$S/sky.exr" -W 128 -H 128 --same-samples -o $F
expect "disk full: envcheck cubemap" "outdir/cube.*: .*$FULL" outdir/cube.exr \
    limited 1 $ENVCHECK "$S/sky.exr" --size 32 -o outdir/cube
oiiotool --pattern noise:type=uniform:min=0.1:max=1 128x64 3 -d float -o noisy.exr > /dev/null 2>&1
expect "disk full: compare heat map" "outdir/heat\.png: .*$FULL" outdir/heat.png \
    limited 4 $COMPARE noisy.exr "$S/sky.exr" --heatmap outdir/heat.png

echo "bad inputs: $cases cases, $failures failure(s)"
[ $failures -eq 0 ]
