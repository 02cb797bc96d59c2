#!/bin/bash
# Issue 31: each error group of 'standard' alone, 100 cases, for the laws given as arguments
# run from the repository root: bash research/notes/scripts/issue-31-error-groups.sh OUT_DIR LAW...
set -eu
Z3='[0,0,0]'
NAV="\"nav_position_bias_m\":$Z3,\"nav_velocity_bias_m_s\":$Z3,\"nav_position_noise_m\":$Z3,\"nav_velocity_noise_m_s\":$Z3"
ENTRY="\"entry_position_m\":$Z3,\"entry_velocity_m_s\":$Z3"
declare -A G
G[entry]="{\"base\":\"standard\",$NAV,\"thrust_scale\":0,\"isp_scale\":0,\"misalignment_rad\":0,\"mass_kg\":0}"
G[thrust]="{\"base\":\"standard\",$NAV,$ENTRY,\"isp_scale\":0,\"misalignment_rad\":0,\"mass_kg\":0}"
G[isp]="{\"base\":\"standard\",$NAV,$ENTRY,\"thrust_scale\":0,\"misalignment_rad\":0,\"mass_kg\":0}"
G[misalignment]="{\"base\":\"standard\",$NAV,$ENTRY,\"thrust_scale\":0,\"isp_scale\":0,\"mass_kg\":0}"
G[mass]="{\"base\":\"standard\",$NAV,$ENTRY,\"thrust_scale\":0,\"isp_scale\":0,\"misalignment_rad\":0}"
G[navigation]="{\"base\":\"standard\",$ENTRY,\"thrust_scale\":0,\"isp_scale\":0,\"misalignment_rad\":0,\"mass_kg\":0}"
OUT=$1; shift
for g in entry thrust isp misalignment mass navigation; do
  python -m agents.campaign --env LunarPinpointLanding-v2 --uncertainty "${G[$g]}" \
     --cases 100 --workers 2 --no-plots --out "$OUT/$g" --json "$OUT/$g.json" --laws "$@" 2>&1 | grep -A20 "^law " | head -8
  echo "== $g"
done
