// Relay with waits (WaitUntil, PauseFor, PauseWhile, PauseUntil).
// The ground station waits 2 s, both drones arm and take off. Drone1 flies
// 6 m north; Drone2 starts its leg as soon as Drone1 is 3 m north
// (WaitUntil). Drone1 then hovers while Drone2 is less than 3 m north
// (Drone1.PauseWhile) before turning east; Drone2 waits for that turn
// (a bare PauseUntil: it runs on Drone1, whose position it reads).
package RelayWait

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Relay() {
	PauseFor(2)
	PAR_Arm()
	PAR_Takeoff()
	PAR_Relay()
	PAR_Home()
	PAR_Land()
}

func PAR_Arm() {
	Drone1.Arm()
	Drone2.Arm()
}

func PAR_Takeoff() {
	Drone1.Takeoff(2)
	Drone2.Takeoff(4)
}

func PAR_Relay() {
	SEQ_Lead()
	WaitUntil(Drone1.X() > 3, SEQ_Chase)
}

func SEQ_Lead() {
	Drone1.FlyByX(6)
	PauseFor(1)
	Drone1.PauseWhile(Drone2.X() < 3)
	Drone1.FlyByY(3)
}

func SEQ_Chase() {
	Drone2.FlyByX(6)
	PauseUntil(Drone1.Y() > 2)
	Drone2.PauseFor(1)
}

func PAR_Home() {
	Drone1.FlyToXYZ(0, 0, 2)
	Drone2.FlyToXYZ(0, 0, 4)
}

func PAR_Land() {
	SEQ_Land1()
	SEQ_Land2()
}

func SEQ_Land1() {
	Drone1.Land()
	Drone1.Disarm()
}

func SEQ_Land2() {
	Drone2.Land()
	Drone2.Disarm()
}
