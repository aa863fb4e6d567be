// missions/first.go, the README's first mission: two drones take off together, Drone1
// flies 5 m north, Drone2 follows once Drone1 is past 4 m, and both land.
var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Main() {
    PAR_Arm()
    PAR_Takeoff()                 // both at once
    Drone1.FlyByX(5)              // then Drone1 alone
    WaitUntil(Drone1.X() > 4, SEQ_Follow)
    PAR_Land()                    // they disarm by themselves once landed
}
func PAR_Arm()     { Drone1.Arm(); Drone2.Arm() }
func PAR_Takeoff() { Drone1.Takeoff(2); Drone2.Takeoff(3) }
func SEQ_Follow()  { Drone2.FlyToXYZ(4, 2, 3) }
func PAR_Land()    { Drone1.Land(); Drone2.Land() }
