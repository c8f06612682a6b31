#!/usr/bin/env bash
# DDS Security for a scenario's members (docs/deployment.md, "DDS Security"): a certificate
# authority, one identity (certificate and key) per member of the scenario and for the
# coordinator, a governance document (authentication required, RTPS messages and data
# encrypted) and a permissions document that lets each member write exactly its own topics:
# a vehicle its state, ruts and sensor samples, its controller its driver commands (in its
# vehicle's partition only: no other vehicle's reader ever matches them), the sensor process its
# images, the coordinator the grants; with soil routing, vehicles and the recorder the ruts
# addressed to another vehicle (in that vehicle's partition); everyone may read.
#
#   launch_scripts/make_security.sh SCENARIO.yaml [--output DIR] [--observer NAME]...
#
# DIR (default: security/ beside the scenario) then holds ca.cert.pem, governance.p7s,
# permissions.p7s and identities/<member>.{cert,key}.pem ("controller/a" -> controller.a).
# --observer NAME adds an identity that may only read (for tools, and for the tests' intruder).
# The CA key (ca.key.pem) signs; keep it off the hosts that only run members. Needs openssl.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
die() { echo "make_security: $*" >&2; exit 1; }
[ $# -ge 1 ] || die "usage: make_security.sh SCENARIO.yaml [--output DIR] [--observer NAME]..."
SCENARIO=$1; shift
[ -f "$SCENARIO" ] || die "scenario file not found: $SCENARIO"
OUT=$(dirname "$SCENARIO")/security; OBSERVERS=()
while [ $# -gt 0 ]; do
  case "$1" in
    --output) OUT=$2; shift ;;
    --observer) OBSERVERS+=("$2"); shift ;;
    *) die "unknown option: $1" ;;
  esac
  shift
done
command -v openssl > /dev/null || die "openssl is missing (apt-get install openssl)"
members=$("$BIN/syndds_coordinator" "$SCENARIO" --print-members 2> /dev/null) ||
  die "$SCENARIO: cannot read its members (run syndds_coordinator $SCENARIO --print-members)"
mkdir -p "$OUT/identities"
OUT=$(cd "$OUT" && pwd)
cd "$OUT"

# The CA: its certificate must allow digital signatures (Fast DDS checks the key usage).
cat > ca.cnf <<CNF
[req]
distinguished_name = dn
prompt = no
[dn]
C = US
O = syndds
CN = syndds CA
[ca]
basicConstraints = critical, CA:TRUE
keyUsage = critical, digitalSignature, keyCertSign, cRLSign
subjectKeyIdentifier = hash
[member]
basicConstraints = CA:FALSE
keyUsage = critical, digitalSignature, keyAgreement
CNF
if [ ! -f ca.key.pem ]; then
  openssl ecparam -name prime256v1 -genkey -noout -out ca.key.pem
  openssl req -x509 -new -key ca.key.pem -config ca.cnf -extensions ca -days 3650 -out ca.cert.pem
fi

file_of() { echo "${1//\//.}"; }
subject_of() { echo "CN=$1,O=syndds,C=US"; }  # RFC 2253 order, as permissions want it
identity() {  # $1 = member name
  local f; f=identities/$(file_of "$1")
  openssl ecparam -name prime256v1 -genkey -noout -out "$f.key.pem"
  # (a '/' inside a value is escaped in openssl's -subj syntax)
  openssl req -new -key "$f.key.pem" -subj "/C=US/O=syndds/CN=${1//\//\\/}" -out "$f.csr"
  openssl x509 -req -in "$f.csr" -CA ca.cert.pem -CAkey ca.key.pem -CAcreateserial \
    -extfile ca.cnf -extensions member -days 3650 -out "$f.cert.pem" 2> /dev/null ||
    die "cannot sign the certificate of $1"
  rm -f "$f.csr"
}

# Topics (docs/protocol.md, "Topics and QoS") each kind of member writes.
protocol_out_coordinator="syndds/member_announce syndds/frame_grant syndds/run_control"
protocol_out_member="syndds/member_announce syndds/frame_done"
data_out_vehicle="syndds/vehicle_state syndds/terrain_deformation syndds/collision_event
  syndds/terrain_snapshot syndds/gps_fix syndds/imu syndds/magnetometer syndds/wheel_speeds
  syndds/v2v_message syndds/vehicle_event syndds/soil_interest"
# Addressed topics (soil routing): a sample goes to the partition of the vehicle it is for.
addressed_out_vehicle="syndds/terrain_patch"
data_out_recorder="syndds/terrain_snapshot"
addressed_out_recorder="syndds/terrain_patch"
data_out_controller="syndds/driver_command syndds/vehicle_event"
data_out_sensor="syndds/image syndds/point_cloud syndds/radar"
topics_xml() { for t in $1; do printf '            <topic>%s</topic>\n' "$t"; done; }

publish_rule() {  # $1 = topics written, then the partitions they may go to
  local topics=$1 p
  shift
  cat <<XML
      <allow_rule>
        <domains><id_range><min>0</min><max>232</max></id_range></domains>
        <publish>
          <topics>
$(topics_xml "$topics")
          </topics>
          <partitions>
XML
  for p in "$@"; do printf '            <partition>%s</partition>\n' "$p"; done
  cat <<XML
          </partitions>
        </publish>
      </allow_rule>
XML
}

grant() {  # $1 = name, $2 = protocol topics written, $3 = data topics written, $4 = vehicle id,
           # $5 = addressed topics written (to any vehicle's partition)
  cat <<XML
    <grant name="$(file_of "$1")">
      <subject_name>$(subject_of "$1")</subject_name>
      <validity><not_before>2020-01-01T00:00:00</not_before><not_after>2100-01-01T00:00:00</not_after></validity>
XML
  if [ -n "$2" ]; then publish_rule "$2" '*'; fi
  # A vehicle's samples go to "<run>/all" and "<run>/vehicle/<id>" (services/dds/participant.cpp):
  # no other partition is allowed, so they can never reach another vehicle's readers.
  if [ -n "$3" ]; then publish_rule "$3" '*/all' "*/vehicle/$4"; fi
  if [ -n "${5:-}" ]; then publish_rule "$5" '*/all' '*/vehicle/*'; fi
  cat <<XML
      <allow_rule>
        <domains><id_range><min>0</min><max>232</max></id_range></domains>
        <subscribe>
          <topics><topic>*</topic></topics>
          <partitions><partition>*</partition></partitions>
        </subscribe>
      </allow_rule>
      <default>DENY</default>
    </grant>
XML
}

{
  echo '<?xml version="1.0" encoding="UTF-8"?>'
  echo '<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">'
  echo '  <permissions>'
  identity coordinator
  grant coordinator "$protocol_out_coordinator" "" ""
  for m in $members; do
    identity "$m"
    id=${m#*/}
    case "$m" in
      vehicle/*) grant "$m" "$protocol_out_member" "$data_out_vehicle" "$id" "$addressed_out_vehicle" ;;
      recorder) grant "$m" "$protocol_out_member" "$data_out_recorder" "" "$addressed_out_recorder" ;;
      controller/*|external/*) grant "$m" "$protocol_out_member" "$data_out_controller" "$id" ;;
      sensor/*) grant "$m" "$protocol_out_member" "$data_out_sensor" "$id" ;;
      *) grant "$m" "$protocol_out_member" "" "" ;;
    esac
  done
  for o in "${OBSERVERS[@]}"; do
    identity "$o"
    grant "$o" "" "" ""
  done
  echo '  </permissions>'
  echo '</dds>'
} > permissions.xml

cat > governance.xml <<'XML'
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <domain_access_rules>
    <domain_rule>
      <domains><id_range><min>0</min><max>232</max></id_range></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>ENCRYPT</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
XML

for doc in governance permissions; do
  openssl smime -sign -in $doc.xml -text -out $doc.p7s -signer ca.cert.pem -inkey ca.key.pem
done
rm -f ca.cert.srl
echo "make_security: $(echo $members | wc -w) members + coordinator${OBSERVERS:+ + ${#OBSERVERS[@]} observers} in $OUT"
