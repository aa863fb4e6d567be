// Experiment D (Listing 13 of the EAMOS paper, missions/experiment_d.go) with one
// addition: PAR_Land lands D1 and D2 once the loops have ended.  As printed, the
// listing leaves the two real drones hovering, so the pre-flight check refuses it
// and a run of it does not finish; this one ends with every drone landed (and
// disarmed by its autopilot a moment later).
// Fly it with the scripted pilot standing in for D3's:
//   eamos run missions/experiment_d_lands.go --fleet configs/experiment_d_pilot.toml
func SEQ_Experiment_D() {
	D1.Arm()
	D2.Arm()
	D3.Arm()
	PAR_1()
	SEQ_2()
	PAR_Loop()
	PAR_Land()
}

// Not in Listing 13: once the loops have ended, land the two real drones too.
func PAR_Land() {
	D1.Land()
	D2.Land()
}

func PAR_1() {
	D1.Arm()
	D2.Arm()
	D3.Arm()
}

func SEQ_2() {
	D1.Takeoff(1)
	D2.Takeoff(1)
	D3.Takeoff(1)
}

func PAR_Loop() {
	RepeatWhile(
		D3.X() > -30 && D3.X() < 30 && D3.Y() > -30 && D3.Y() < 30,
		SEQ_IsD1XUp, PAR_Exit)

	RepeatWhile(
		D3.X() > -30 && D3.X() < 30 && D3.Y() > -30 && D3.Y() < 30,
		SEQ_IsD1XDown, PAR_Exit)

	RepeatWhile(
		D3.X() > -30 && D3.X() < 30 && D3.Y() > -30 && D3.Y() < 30,
		SEQ_IsD2XUp, PAR_Exit)

	RepeatWhile(
		D3.X() > -30 && D3.X() < 30 && D3.Y() > -30 && D3.Y() < 30,
		SEQ_IsD2XDown, PAR_Exit)
}

func SEQ_IsD1XUp() {
	WaitUntil(
		D3.X() > -20 && D3.X() < -10 &&
			D3.Y() > -15 && D3.Y() < -5,
		SEQ_upXD1)
}

func SEQ_IsD1XDown() {
	WaitUntil(
		D3.X() < -10 && D3.X() > -20 &&
			D3.Y() > 5 && D3.Y() < 10,
		SEQ_downXD1)
}

func SEQ_IsD2XUp() {
	WaitUntil(
		D3.X() < 20 && D3.X() > 10 &&
			D3.Y() < -5 && D3.Y() > -15,
		SEQ_upXD2)
}

func SEQ_IsD2XDown() {
	WaitUntil(
		D3.X() > 10 && D3.X() < 20 &&
			D3.Y() < 10 && D3.Y() > 5,
		SEQ_downXD2)
}

func SEQ_upXD1() {
	D1.FlyByX(0.2)
}

func SEQ_downXD1() {
	D1.FlyByX(-0.2)
}

func SEQ_upXD2() {
	D2.FlyByX(0.2)
}

func SEQ_downXD2() {
	D2.FlyByX(-0.2)
}

func PAR_Exit() {
	D3.Land()
}
